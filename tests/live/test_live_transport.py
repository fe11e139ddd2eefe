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


# ---------------------------------------------------------------- groups (no peer lists)
GROUP = "239.255.71.1"  # (administratively scoped: a LAN's own; joined on loopback here)
BROADCAST = "127.255.255.255"


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((LOCAL, 0))
        return s.getsockname()[1]


def group_or_skip(transports, mode: str, address: tuple[str, int]) -> UdpTransport:
    """A transport in ``mode``, or a skip saying the kernel's reason where it refuses."""
    try:
        return transports(address, mode=mode)
    except TransportError as exc:
        pytest.skip(f"the kernel refuses UDP {mode} on loopback here: {exc}")


@pytest.mark.parametrize(("mode", "host"), [("multicast", GROUP), ("broadcast", BROADCAST)])
def test_a_group_reaches_every_member_without_a_peer_list(transports, mode, host):
    """Two transports share one port of the group (SO_REUSEPORT), neither lists the other:
    each datagram reaches both, its sender's looped back (as a unicast sender's own copy
    comes back: the receiver skips its own agents' copies)."""
    port = free_port()
    a = group_or_skip(transports, mode, (host, port))
    b = group_or_skip(transports, mode, (host, port))
    assert a.address == b.address == (host, port) and a.peers == [(host, port)]
    a.send(b"from a", "data")
    b.send(b"from b", "control")
    assert sorted(drain(a, 2)) == [b"from a", b"from b"]
    assert sorted(drain(b, 2)) == [b"from a", b"from b"]
    assert a.send_errors == b.send_errors == 0


def test_a_group_port_held_without_sharing_is_one_line(transports):
    port = free_port()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.bind(("", port))  # (every address, not sharing: as a foreign program may)
        with pytest.raises(TransportError) as err:
            transports((GROUP, port), mode="multicast")
    assert str(err.value) == (
        f"UDP multicast {GROUP}:{port} is taken (another process "
        "listens there without sharing the port)"
    )


@pytest.mark.parametrize(
    ("mode", "host", "interface", "message"),
    [
        ("multicast", "10.1.2.3", LOCAL, "UDP multicast: '10.1.2.3' is not a multicast group"),
        (
            "multicast",
            "robots.local",
            LOCAL,
            "UDP multicast: 'robots.local' is not an IPv4 address",
        ),
        ("broadcast", "::1", LOCAL, "UDP broadcast: '::1' is not an IPv4 address"),
        (
            "multicast",
            GROUP,
            "eth9",
            f"cannot join UDP multicast {GROUP}:0 on interface eth9: not an IPv4 address",
        ),
    ],
)
def test_a_bad_group_or_interface_is_one_line(transports, mode, host, interface, message):
    with pytest.raises(TransportError) as err:
        transports((host, 0), mode=mode, interface=interface)
    assert str(err.value).startswith(message) and "\n" not in str(err.value)
