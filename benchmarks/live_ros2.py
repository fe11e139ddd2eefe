"""Round trip of a datagram over the ros2 transport on this machine (p50, p99, max).

Two transports of one team in one process, each with its own rclpy context (so its own DDS
participant, as two agent processes have): ``a`` sends a datagram on the control socket,
``b`` waits for it and sends it back, ``a`` waits for the answer. A round trip is the
monotonic time from ``a``'s send to the answer in ``a``'s hands: two publications, two
deliveries through each executor thread, two wake-ups of ``wait``. One-way latency is about
half of it. The issue's budget for the UDP transport, a datagram's arrival to the mode change
at most 5 ms p99, is the figure to hold this against. Needs the ``ros`` extra.

    python benchmarks/live_ros2.py [--count N] [--size BYTES]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

from hybridteam.live.ros2 import Ros2Transport


def until(condition, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise SystemExit("the two transports did not discover each other")
        time.sleep(0.005)


def round_trips(count: int, size: int) -> list[float]:
    domain = 1 + os.getpid() % 100
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    a = Ros2Transport("bench", "a", ["control"], domain_id=domain)
    b = Ros2Transport("bench", "b", ["control"], domain_id=domain)
    try:
        until(lambda: a.peers("control") == 1 and b.peers("control") == 1, 10.0)
        payload = bytes(range(256)) * (size // 256) + bytes(size % 256)
        out = []
        for i in range(count + 50):  # the first 50 warm the caches and are not counted
            t0 = time.monotonic()
            a.send(payload, "control")
            while not (got := b.receive()):
                b.wait(1.0)
            b.send(got[0][0], "control")
            while not (back := a.receive()):
                a.wait(1.0)
            if i >= 50:
                out.append(time.monotonic() - t0)
            assert back[0][0] == payload
    finally:
        a.close()
        b.close()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=2000, help="round trips (default 2000)")
    parser.add_argument("--size", type=int, default=100, help="datagram bytes (default 100)")
    args = parser.parse_args()
    trips = sorted(round_trips(args.count, args.size))
    p99 = trips[min(len(trips) - 1, int(0.99 * len(trips)))]
    print(f"ros2 transport, loopback round trip of a {args.size}-byte datagram, {len(trips)} trips")
    print(
        f"  p50 {statistics.median(trips) * 1e3:.3f} ms   p99 {p99 * 1e3:.3f} ms   "
        f"max {trips[-1] * 1e3:.3f} ms"
    )


if __name__ == "__main__":
    main()
