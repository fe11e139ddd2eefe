"""The live runtime: a compiled team's agents as processes over real datagrams, in
wall-clock time (see docs/live.md).

Above the engine: it uses the engine's seams (the simulator's clock, the network's outlet
and arrivals) and never a private engine name; the engine never imports it.
:mod:`.wire` is the datagram format, :mod:`.transport` the transports, :mod:`.hosting`
what a process runs of the team, :mod:`.clock` the wall clock and the outlet,
:mod:`.run` one live process's run, :mod:`.merge` the team trace of a run's processes,
:mod:`.counterexample` a ``verify`` counterexample's losses as a live run's scripted drops.
"""
