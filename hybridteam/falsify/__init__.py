"""Falsification: a search for the run that breaks a requirement (``hybridteam falsify``).

:mod:`.search` proposes candidates (random, or differential evolution), :mod:`.evaluate`
simulates each generation as ensembles, :mod:`.output` writes the folder.
"""
