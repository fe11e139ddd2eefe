"""UdpTransport on loopback: addressing, batches, waiting, closing (every socket a test
opens is closed by it)."""

from __future__ import annotations

import socket
import time

import pytest

from hybridteam.live.transport import TransportError, UdpTransport

LOCAL = "127.0.0.1"


@pytest.fixture
def transports():
    made: list[UdpTransport] = []

    def make(*args, **kwargs) -> UdpTransport:
        made.append(UdpTransport(*args, **kwargs))
        return made[-1]

    yield make
    for t in made:
        t.close()


def drain(t: UdpTransport, count: int, timeout: float = 10.0) -> list[bytes]:
    got: list[bytes] = []
    end = time.monotonic() + timeout
    while len(got) < count and time.monotonic() < end:
        if t.wait(0.1):
            got += [data for data, _ in t.receive()]
    return got


def test_a_datagram_goes_to_every_peer_and_back_to_its_sender(transports):
    a = transports((LOCAL, 0))
    b = transports((LOCAL, 0), [a.address])
    assert b.peers == [a.address, b.address]
    before = time.monotonic()
    b.send(b"hello", "control")
    assert a.wait(10.0) is True
    ((data, arrived),) = a.receive()
    assert data == b"hello" and before <= arrived <= time.monotonic()
    assert drain(b, 1) == [b"hello"]
    assert a.wait(0.0) is False and a.receive() == []  # nothing else waits


def test_a_flood_comes_in_batches(transports):
    """25 datagrams waiting, batches of 10: three calls return 10, 10 and 5, in order."""
    t = transports((LOCAL, 0), batch=10)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for k in range(25):
            s.sendto(str(k).encode(), t.address)
    time.sleep(0.2)  # (loopback delivers at once; the pause makes sure)
    sizes, got = [], []
    for _ in range(3):
        batch = t.receive()
        sizes.append(len(batch))
        got += [int(d) for d, _ in batch]
    assert sizes == [10, 10, 5]
    assert got == list(range(25))


def test_a_taken_port_is_one_line(transports):
    a = transports((LOCAL, 0))
    host, port = a.address
    with pytest.raises(TransportError) as err:
        transports((LOCAL, port))
    assert str(err.value) == f"UDP port {host}:{port} is taken (another process listens there)"


def test_close_is_idempotent(transports):
    t = transports((LOCAL, 0))
    t.close()
    t.close()
    assert t.wait(0.0) is False
