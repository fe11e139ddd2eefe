"""Transports: how a live process's datagrams reach its teammates' processes.

Every transport has the :class:`Transport` shape: the engine's outlet hands it encoded datagrams
(:mod:`~hybridteam.live.wire`) with the team's socket name, and the wall clock
(:mod:`~hybridteam.live.clock`) asks it for what arrived, with arrival times on
``time.monotonic()``, or waits on it until something does. :class:`UdpTransport` is the paper's
medium: UDP datagrams on a LAN or on loopback; ROS 2 topics are another implementation.
"""

from __future__ import annotations

import errno
import select
import socket as sockets
import time
from typing import Protocol

#: Read buffer: a UDP datagram's largest size, so an oversized one is read whole (and
#: dropped by the decoder) rather than truncated into something else.
READ_BYTES = 65535
#: The most datagrams one ``receive`` returns: a flood arriving faster than it is read
#: must not hold the caller (the run's loop) in one call; the rest wait for the next.
BATCH = 1024


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


Address = tuple[str, int]


class UdpTransport:
    """One UDP port per process; every datagram goes to each peer and to this port.

    The team's socket name travels inside the datagram, so one port serves ``data`` and
    ``control``. Sending to this process's own port is how agents sharing a process talk
    (through the socket, as they would across machines). On a LAN, each machine's
    process listens on its own address and names the others' as peers (broadcast and
    multicast groups, which need no peer list, are not built yet)."""

    def __init__(self, listen: Address = ("127.0.0.1", 47000),
                 peers: list[Address] | tuple[Address, ...] = (), batch: int = BATCH) -> None:
        self.sock = sockets.socket(sockets.AF_INET, sockets.SOCK_DGRAM)
        try:
            self.sock.bind(listen)
        except OSError as exc:
            self.sock.close()
            host, port = listen
            if exc.errno == errno.EADDRINUSE:
                raise TransportError(f"UDP port {host}:{port} is taken (another process "
                                     "listens there)") from None
            raise TransportError(f"cannot listen on UDP {host}:{port}: "
                                 f"{exc.strerror or exc}") from None
        self.sock.setblocking(False)
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
