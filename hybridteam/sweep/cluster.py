"""Reaching a Dask scheduler, in bounded time, with one line when it cannot be reached.

``--scheduler`` is an address someone typed, and ``dask.distributed`` trusts what answers
there: a port that answers with anything else (an HTTP server) has its first eight bytes
read as a message length and gets a buffer of that size allocated (``HTTP/1.1`` asks for
3 EiB), and a server that accepts and says nothing keeps the client waiting forever.
Before the client connects, :func:`connect` therefore reads the address with Dask's own
parser and, for plain TCP, opens the connection itself and checks that what answers
speaks first as a Dask server does — a length-prefixed handshake of plausible size —
within ``timeout`` seconds (:data:`DEFAULT_CONNECT_TIMEOUT`, ``--connect-timeout``). Only
then does Dask's client connect (with the same timeout). Every failure is a
:class:`~hybridteam.sweep.store.StudyError` naming the address and what went wrong.
"""

from __future__ import annotations

import socket
import struct
import time
from typing import Any

from hybridteam.sweep.store import StudyError

#: seconds to connect to a scheduler and hear its handshake
DEFAULT_CONNECT_TIMEOUT = 10.0
#: a scheduler's handshake is a few hundred bytes; a length beyond this is not Dask's
MAX_HANDSHAKE = 1 << 20
_LENGTH = struct.Struct("<Q")


def connect(scheduler: str, timeout: float = DEFAULT_CONNECT_TIMEOUT) -> Any:
    """A ``dask.distributed.Client`` of the scheduler at ``scheduler`` (see the module)."""
    try:
        from dask.distributed import Client
        from distributed.comm.addressing import parse_address, parse_host_port
    except ImportError:
        raise StudyError(
            "running on a Dask cluster needs dask.distributed: pip install 'hybridteam[dask]'"
        ) from None
    where = f"the Dask scheduler at {scheduler!r}"
    try:
        scheme, location = parse_address(scheduler)
        host, port = parse_host_port(location) if scheme == "tcp" else (None, None)
    except (TypeError, ValueError) as exc:
        raise StudyError(
            f"{where}: not an address ({exc}); expected e.g. tcp://HOST:8786"
        ) from None
    if host is not None and port is not None:  # (dask gives a host a port or refuses it)
        _probe(where, host, int(port), timeout)
    try:
        return Client(scheduler, timeout=f"{timeout}s")
    except (OSError, TimeoutError, ValueError, MemoryError) as exc:
        raise StudyError(f"cannot reach {where}: {exc}") from None


def _probe(where: str, host: str, port: int, timeout: float) -> None:
    """Connect to ``host:port`` and read what answers: a Dask server writes its handshake
    first, eight bytes of length and that many bytes."""
    if not 0 < port < 65536:
        raise StudyError(f"{where}: port {port} is not a port number (1 to 65535)")
    deadline = time.monotonic() + timeout
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            head = _read(sock, _LENGTH.size, deadline)
            (size,) = _LENGTH.unpack(head)
            if not 0 < size <= MAX_HANDSHAKE:
                raise StudyError(
                    f"{where} answers, but not as a Dask scheduler (its first "
                    f"bytes {head!r} are no Dask message)"
                )
            _read(sock, size, deadline)
    except EOFError:
        raise StudyError(f"{where} closed the connection without a Dask handshake") from None
    except TimeoutError:
        raise StudyError(
            f"{where} did not answer as a Dask scheduler within {timeout:g} s (--connect-timeout S)"
        ) from None
    except OSError as exc:
        raise StudyError(f"cannot reach {where}: {exc.strerror or exc}") from None


def _read(sock: socket.socket, size: int, deadline: float) -> bytes:
    """Exactly ``size`` bytes before ``deadline``; TimeoutError if they do not come in
    time, EOFError if the connection closes first."""
    out = bytearray()
    while len(out) < size:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError
        sock.settimeout(left)
        chunk = sock.recv(min(size - len(out), 65536))
        if not chunk:
            raise EOFError
        out += chunk
    return bytes(out)
