"""Transports: how a live process's datagrams reach its teammates' processes.

Every transport has the :class:`Transport` shape: the engine's outlet hands it encoded
datagrams (:mod:`~hybridteam.live.wire`) with the team's socket name, and the wall clock
(:mod:`~hybridteam.live.clock`) asks it for what arrived, with arrival times on
``time.monotonic()``, or waits on it until something does. :class:`UdpTransport` is the
paper's medium: UDP datagrams on a LAN or on loopback, to listed peers, to a multicast group
or broadcast; ROS 2 topics are another implementation.
"""

from __future__ import annotations

import errno
import select
import socket as sockets
import time
from typing import Protocol

from hybridteam.model.deploy import LOOPBACK, Address, group_problem

#: Read buffer: a UDP datagram's largest size, so an oversized one is read whole (and
#: dropped by the decoder) rather than truncated into something else.
READ_BYTES = 65535
#: The most datagrams one ``receive`` returns: a flood arriving faster than it is read
#: must not hold the caller (the run's loop) in one call; the rest wait for the next.
BATCH = 1024
#: How a UDP transport reaches its teammates: each listed peer's own port, a multicast
#: group every process joins, or a broadcast address every process listens on.
MODES = ("unicast", "multicast", "broadcast")


class TransportError(OSError):
    """A transport that cannot start (a port taken, an address not here): one line."""


class Transport(Protocol):
    """What the live runtime needs of a transport."""

    def send(self, payload: bytes, socket: str) -> None:
        """Send one datagram on the team's socket ``socket`` ("data" or "control")."""

    def receive(self) -> list[tuple[bytes, float]]:
        """Every datagram waiting, each with its arrival time (``time.monotonic()``);
        never blocks. (A transport may return a bounded batch of them, as
        :class:`UdpTransport` does under a flood: the rest come with the next call.)"""

    def wait(self, timeout: float) -> bool:
        """Block until a datagram is waiting or ``timeout`` seconds pass; True if one is."""

    def close(self) -> None:
        """Release sockets and threads; idempotent."""


class UdpTransport:
    """One UDP socket per process; every datagram goes to each destination, this
    process's own address among them.

    The team's socket name travels inside the datagram, so one socket serves ``data`` and
    ``control``. A process hears its own datagrams (sent to its own port, or looped back
    by the group or the broadcast): that is how agents sharing a process talk, through
    the socket as across machines, and the receiver already skips a copy whose sender is
    its addressee (:class:`~hybridteam.live.clock.WallClock`), so nothing more is needed
    to discard them. ``mode``:

    * ``unicast``: bound to ``listen``, sending to each of ``peers`` (every other
      process's address must be listed);
    * ``multicast``: ``listen`` is the group and port (an IPv4 multicast address); the
      socket is bound to it and joins it on ``interface`` (loopback by default; a LAN
      address, or 0.0.0.0 for the kernel's choice), with loop-back on and a time-to-live
      of 1 (the LAN only). No process lists another;
    * ``broadcast``: ``listen`` is a broadcast address and port (127.255.255.255 on
      loopback, the subnet's, or 255.255.255.255), bound and sent to.

    In the two group modes the port is shared (SO_REUSEADDR, SO_REUSEPORT), so that
    several processes of one machine listen on it together; ``peers`` are then extra
    destinations (none are needed)."""

    def __init__(
        self,
        listen: Address = (LOOPBACK, 47000),
        peers: list[Address] | tuple[Address, ...] = (),
        batch: int = BATCH,
        *,
        mode: str = "unicast",
        interface: str = LOOPBACK,
    ) -> None:
        if mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
        host, port = listen
        problem = group_problem(mode, host) if mode != "unicast" else None
        if problem is not None:
            raise TransportError(f"UDP {mode}: {problem}")
        self.sock = sockets.socket(sockets.AF_INET, sockets.SOCK_DGRAM)
        try:
            if mode != "unicast":  # (several processes of one machine share the port)
                self.sock.setsockopt(sockets.SOL_SOCKET, sockets.SO_REUSEADDR, 1)
                self.sock.setsockopt(sockets.SOL_SOCKET, sockets.SO_REUSEPORT, 1)
            if mode == "broadcast":
                self.sock.setsockopt(sockets.SOL_SOCKET, sockets.SO_BROADCAST, 1)
            self.sock.bind(listen)
            if mode == "multicast":
                _join(self.sock, host, interface)
        except OSError as exc:
            self.sock.close()
            raise _start_error(exc, mode, host, port, interface) from None
        self.sock.setblocking(False)
        self.mode = mode
        self.address: Address = self.sock.getsockname()
        self.peers = [*dict.fromkeys([*peers, self.address])]
        self.batch = batch
        self.sent = 0
        self.send_errors = 0
        self.closed = False

    def send(self, payload: bytes, socket: str) -> None:
        for peer in self.peers:
            try:
                self.sock.sendto(payload, peer)
                self.sent += 1
            except OSError:  # a peer not listening (ICMP refused), a full buffer: lost,
                self.send_errors += 1  # as a datagram may be

    def receive(self) -> list[tuple[bytes, float]]:
        out: list[tuple[bytes, float]] = []
        for _ in range(self.batch):  # (errors count too: none can hold the caller)
            try:
                data = self.sock.recv(READ_BYTES)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # an earlier send's ICMP error reported here: nothing to read
                continue
            out.append((data, time.monotonic()))
        return out

    def wait(self, timeout: float) -> bool:
        if self.closed:
            return False
        ready, _, _ = select.select([self.sock], [], [], max(timeout, 0.0))
        return bool(ready)

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self.sock.close()


def _join(sock: sockets.socket, group: str, interface: str) -> None:
    """Join ``group`` on ``interface`` and send to it from there, hearing this machine's
    own datagrams (its other processes, and this one's agents), one hop only."""
    try:
        where = sockets.inet_aton(interface)
    except OSError:
        raise OSError(errno.EADDRNOTAVAIL, "not an IPv4 address") from None
    sock.setsockopt(sockets.IPPROTO_IP, sockets.IP_ADD_MEMBERSHIP, sockets.inet_aton(group) + where)
    sock.setsockopt(sockets.IPPROTO_IP, sockets.IP_MULTICAST_IF, where)
    sock.setsockopt(sockets.IPPROTO_IP, sockets.IP_MULTICAST_LOOP, 1)
    sock.setsockopt(sockets.IPPROTO_IP, sockets.IP_MULTICAST_TTL, 1)


def _start_error(exc: OSError, mode: str, host: str, port: int, interface: str) -> TransportError:
    """The one line for a socket that could not be set up: a taken port, an address that
    is not this machine's, an interface that cannot join the group."""
    where = f"UDP {mode} {host}:{port}" if mode != "unicast" else f"UDP port {host}:{port}"
    if exc.errno == errno.EADDRINUSE:
        return TransportError(
            f"{where} is taken (another process listens there"
            + (" without sharing the port)" if mode != "unicast" else ")")
        )
    if mode == "multicast" and exc.errno in (errno.EADDRNOTAVAIL, errno.ENODEV, errno.EINVAL):
        return TransportError(
            f"cannot join {where} on interface {interface}: {exc.strerror or exc}"
        )
    where = f"UDP {mode} {host}:{port}" if mode != "unicast" else f"UDP {host}:{port}"
    return TransportError(f"cannot listen on {where}: {exc.strerror or exc}")
