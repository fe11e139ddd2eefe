"""The ``deploy:`` section: where a team's agents run when they run live.

The team file's ``deploy:`` section maps agent names to their settings, and its ``udp``
key holds the team's UDP addressing (docs/live.md); a simulation ignores the section.
Plain data here, checked where it is read, so that ``validate`` reports a bad setting at
its line without ROS or a network.

An agent's robot, which ``hybridteam live --plant ros2`` drives through these
(:mod:`hybridteam.live.ros2_plant`)::

    cmd_vel: /scout1/cmd_vel   # required: where Twist commands are published
    odom: /scout1/odom         # required: where Odometry is read
    scan: /scout1/scan         # optional: where LaserScan is read
    frame: odom                # optional, default "odom": the frame poses must be given in
    timeout: 2.0               # optional, default 2 s: how long odometry may be silent

Topics are given by their full names (a relative name would resolve against the plant's own
node, not where the robot's driver publishes).

An agent's UDP address, and the team's (:class:`UdpDeploy`), so that ``hybridteam live
TEAM.yaml --agent a`` on robot ``a`` needs no address flags::

    listen: 192.168.1.11:47000     # an agent's entry: its process's own address
    udp: {peers: [192.168.1.11:47000, 192.168.1.12:47000]}   # every process's address, or
    udp: {multicast: 239.255.0.1:47000, interface: 0.0.0.0}  # a group every process joins,
    udp: {broadcast: 192.168.1.255:47000}                    # or a broadcast address
"""

from __future__ import annotations

import ipaddress
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from hybridteam.errors import DocPath, ModelError, did_you_mean

#: a topic's full name: relative ones would resolve against the plant node's namespace
_TOPIC = re.compile(r"(/[A-Za-z_]([A-Za-z0-9]|_(?!_))*)+")

_KEYS = ("cmd_vel", "odom", "scan", "frame", "timeout")
#: the keys of an agent's entry: its robot's, and its process's UDP address
AGENT_KEYS = (*_KEYS, "listen")
#: the ``deploy:`` key that holds the team's UDP addressing rather than an agent's entry
UDP = "udp"
#: how UDP datagrams reach the team: one of these keys in ``deploy: udp:``
UDP_MODES = ("peers", "multicast", "broadcast")
#: the interface a multicast group is joined on unless told: loopback (one machine)
LOOPBACK = "127.0.0.1"

Address = tuple[str, int]


def parse_address(text: object) -> Address:
    """``HOST:PORT`` as a socket address; ValueError saying what it must be otherwise."""
    host, sep, port = text.rpartition(":") if isinstance(text, str) else ("", "", "")
    if (
        not sep
        or not host
        or not (port.isascii() and port.isdigit())
        or not 0 <= int(port) <= 65535
    ):
        raise ValueError(f"must be HOST:PORT with a port from 0 to 65535, got '{text}'")
    return host, int(port)


def group_problem(mode: str, host: str) -> str | None:
    """Why ``host`` cannot be a ``multicast`` group or a ``broadcast`` address (IPv4
    only; a group in 224.0.0.0/4), or None."""
    try:
        address = ipaddress.IPv4Address(host)
    except ValueError:
        return f"'{host}' is not an IPv4 address"
    if mode == "multicast" and not address.is_multicast:
        return (
            f"'{host}' is not a multicast group (224.0.0.0 to 239.255.255.255; "
            "239.x.x.x for a LAN's own)"
        )
    return None


@dataclass(frozen=True)
class UdpDeploy:
    """The team's UDP addressing from its ``deploy:`` section: ``mode`` ``peers`` (each
    process sends to every address of ``peers``), ``multicast`` or ``broadcast`` (every
    process shares ``group``, a multicast group or a broadcast address, and port), or
    None when the file says nothing; ``interface``: where a multicast group is joined;
    ``listen``: per agent, its process's own address (``peers`` mode)."""

    mode: str | None = None
    peers: tuple[Address, ...] = ()
    group: Address | None = None
    interface: str = LOOPBACK
    listen: Mapping[str, Address] = field(default_factory=dict)

    @classmethod
    def from_mapping(cls, config: Any, path: DocPath = (UDP,)) -> UdpDeploy:
        """The checked ``udp:`` setting (no ``listen`` yet), or a :class:`ModelError` at
        ``path`` + the offending key."""
        keys = (*UDP_MODES, "interface")
        if not isinstance(config, Mapping):
            raise ModelError(
                path,
                "expected a mapping with one of peers, multicast, "
                "broadcast (and interface, with multicast)",
            )
        for key in config:
            if key not in keys:
                raise ModelError(
                    (*path, key),
                    f"unknown udp setting {key!r}",
                    hint=did_you_mean(str(key), keys),
                    at_key=True,
                )
        given = [k for k in UDP_MODES if k in config]
        if len(given) != 1:
            raise ModelError(
                path,
                "give exactly one of peers, multicast, broadcast"
                + (f" (got {', '.join(given)})" if given else ""),
            )
        mode = given[0]
        if "interface" in config and mode != "multicast":
            raise ModelError(
                (*path, "interface"),
                "interface is where a multicast group is joined: it goes with multicast only",
                at_key=True,
            )
        if mode == "peers":
            peers = config["peers"]
            if not isinstance(peers, list) or not peers:
                raise ModelError(
                    (*path, "peers"), "expected a list of HOST:PORT addresses (every process's)"
                )
            return cls(mode, tuple(_address(p, (*path, "peers", k)) for k, p in enumerate(peers)))
        group = _address(config[mode], (*path, mode))
        problem = group_problem(mode, group[0])
        if problem is not None:
            raise ModelError((*path, mode), problem)
        interface = config.get("interface", LOOPBACK)
        if not isinstance(interface, str) or group_problem("interface", interface):
            raise ModelError(
                (*path, "interface"),
                "expected the IPv4 address of this "
                f"machine's interface (0.0.0.0: the kernel's choice), got "
                f"{interface!r}",
            )
        return cls(mode, group=group, interface=interface)


def agent_deploy(config: Any, path: DocPath) -> tuple[PlantDeploy | None, Address | None]:
    """One agent's entry: its robot's settings (None if it names no topic) and its UDP
    ``listen`` address (None if not given), or a :class:`ModelError` at ``path`` + key."""
    if not isinstance(config, Mapping):
        raise ModelError(path, "expected a mapping of listen, cmd_vel, odom, scan, frame, timeout")
    for key in config:
        if key not in AGENT_KEYS:
            raise ModelError(
                (*path, key),
                f"unknown deploy setting {key!r}",
                hint=did_you_mean(str(key), AGENT_KEYS),
                at_key=True,
            )
    listen = _address(config["listen"], (*path, "listen")) if "listen" in config else None
    robot = {k: v for k, v in config.items() if k != "listen"}
    return (PlantDeploy.from_mapping(robot, path) if robot else None), listen


def _address(text: object, path: DocPath) -> Address:
    try:
        return parse_address(text)
    except ValueError as exc:
        raise ModelError(path, f"expected an address: {exc}") from None


@dataclass(frozen=True)
class PlantDeploy:
    """One agent's ``deploy`` settings: the robot's topics and frame (module docstring)."""

    cmd_vel: str
    odom: str
    scan: str | None = None
    frame: str = "odom"
    timeout: float = 2.0

    @classmethod
    def from_mapping(cls, config: Mapping[str, Any], path: DocPath = ()) -> PlantDeploy:
        """Checked settings, or a :class:`ModelError` at ``path`` + the offending key (the
        YAML layer turns it into file:line:column)."""
        if not isinstance(config, Mapping):
            raise ModelError(path, "expected a mapping of cmd_vel, odom, scan, frame, timeout")
        for key in config:
            if key not in _KEYS:
                raise ModelError(
                    (*path, key),
                    f"unknown deploy setting {key!r}",
                    hint=did_you_mean(str(key), _KEYS),
                    at_key=True,
                )
        for key in ("cmd_vel", "odom"):
            if key not in config:
                raise ModelError(
                    path,
                    f"missing {key!r}: the robot's "
                    + ("Twist command topic" if key == "cmd_vel" else "Odometry topic"),
                )
        for key in ("cmd_vel", "odom", "scan"):
            value = config.get(key)
            if key in config and not (isinstance(value, str) and _TOPIC.fullmatch(value)):
                raise ModelError(
                    (*path, key),
                    f"expected a topic's full name (/name/name..., "
                    "each name letters, digits and single underscores, not "
                    f"starting with a digit), got {value!r}",
                )
        frame = config.get("frame", "odom")
        if not (isinstance(frame, str) and frame):
            raise ModelError((*path, "frame"), f"expected a frame name, got {frame!r}")
        timeout = config.get("timeout", 2.0)
        if (
            isinstance(timeout, bool)
            or not isinstance(timeout, int | float)
            or not 0 < timeout < math.inf
        ):
            raise ModelError(
                (*path, "timeout"), f"expected a number of seconds > 0, got {timeout!r}"
            )
        return cls(config["cmd_vel"], config["odom"], config.get("scan"), frame, float(timeout))
