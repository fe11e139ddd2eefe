"""The UDP addressing of a ``hybridteam live`` process: its flags and the team file's
``deploy:`` section, flags first (docs/live.md, *Addresses in the team file*).

* ``--multicast GROUP:PORT`` or ``--broadcast ADDR:PORT``: every process shares the group
  (or broadcast address) and its port; no process lists another. ``--interface ADDR``:
  where the multicast group is joined (default loopback).
* ``--listen HOST:PORT`` and ``--peer HOST:PORT``: this process's own port, and every other
  process's.
* Without them, the team file says: its ``deploy: udp:`` mode (``peers``, ``multicast``,
  ``broadcast``), and for ``peers`` the hosted agent's ``listen`` address; a flag replaces
  what it names (``--listen`` the agent's address, ``--peer`` the file's peers, and a
  group flag the whole setting). Nothing in either: ``127.0.0.1:47000`` and no peer.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from hybridteam.cli.common import UsageError
from hybridteam.model import Team
from hybridteam.model.deploy import LOOPBACK, Address, parse_address

#: The port a process listens on when neither its flags nor the team file say.
DEFAULT_LISTEN: Address = (LOOPBACK, 47000)


def add_udp_options(parser: argparse.ArgumentParser) -> None:
    """The UDP addressing flags of ``hybridteam live``."""
    parser.add_argument(
        "--listen",
        default=None,
        metavar="HOST:PORT",
        help="this process's UDP address (default: its agent's deploy: "
        "listen, else 127.0.0.1:47000)",
    )
    parser.add_argument(
        "--peer",
        action="append",
        default=[],
        metavar="HOST:PORT",
        help="another process's UDP address (repeat for several)",
    )
    parser.add_argument(
        "--multicast",
        default=None,
        metavar="GROUP:PORT",
        help="send to and hear a multicast group (e.g. 239.255.0.1:47000) instead of listing peers",
    )
    parser.add_argument(
        "--broadcast",
        default=None,
        metavar="ADDR:PORT",
        help="send to and hear a broadcast address (e.g. "
        "192.168.1.255:47000, 127.255.255.255 on loopback)",
    )
    parser.add_argument(
        "--interface",
        default=None,
        metavar="ADDR",
        help="(multicast) the IPv4 address of the interface the group is "
        "joined on (default 127.0.0.1; 0.0.0.0: the kernel's choice)",
    )


@dataclass(frozen=True)
class UdpSettings:
    """Where a process's UDP socket listens and sends (:class:`UdpTransport`'s terms)."""

    mode: str
    listen: Address
    peers: tuple[Address, ...] = ()
    interface: str = LOOPBACK


def address(text: str, flag: str) -> Address:
    """``HOST:PORT`` as a socket address, or UsageError naming the flag."""
    try:
        return parse_address(text)
    except ValueError as exc:
        raise UsageError(f"{flag} {exc}") from None


def check_udp_flags(args: argparse.Namespace) -> None:
    """UsageError for addressing flags that are not addresses or do not go together
    (checked before the team file is read)."""
    for flag in ("listen", "multicast", "broadcast"):
        if getattr(args, flag) is not None:
            address(getattr(args, flag), f"--{flag}")
    for peer in args.peer:
        address(peer, "--peer")
    group = [f"--{f}" for f in ("multicast", "broadcast") if getattr(args, f) is not None]
    if len(group) == 2:
        raise UsageError("give --multicast or --broadcast, not both")
    if group and (args.listen is not None or args.peer):
        raise UsageError(
            f"{group[0]}: every process shares the group's port; --listen and "
            "--peer are for listing peers instead"
        )


def udp_settings(args: argparse.Namespace, team: Team, agents: list[str]) -> UdpSettings:
    """The flags over the team file's ``deploy:`` (module docstring), or UsageError."""
    udp = team.udp
    group: tuple[str, int] | None
    if args.multicast is not None or args.broadcast is not None:
        mode = "multicast" if args.multicast is not None else "broadcast"
        group = address(args.multicast or args.broadcast, f"--{mode}")
    elif args.listen is None and not args.peer and udp.mode in ("multicast", "broadcast"):
        mode, group = udp.mode, udp.group
    else:
        mode, group = "unicast", None
    interface = args.interface if args.interface is not None else udp.interface
    if args.interface is not None and mode != "multicast":
        raise UsageError(
            "--interface is where a multicast group is joined: it goes with "
            "--multicast (or the team file's deploy: udp: multicast)"
        )
    if group is not None:
        assert mode is not None
        return UdpSettings(mode, group, interface=interface)
    peers = (
        tuple(address(p, "--peer") for p in args.peer)
        if args.peer
        else (udp.peers if udp.mode == "peers" else ())
    )
    if args.listen is not None:
        return UdpSettings("unicast", address(args.listen, "--listen"), peers)
    given = {a: udp.listen[a] for a in agents if a in udp.listen}
    if len(set(given.values())) > 1:
        raise UsageError(
            "the agents here listen on different addresses in the team file's "
            "deploy: ("
            + ", ".join(f"{a}: {h}:{p}" for a, (h, p) in given.items())
            + "); give --listen"
        )
    return UdpSettings("unicast", next(iter(given.values()), DEFAULT_LISTEN), peers)
