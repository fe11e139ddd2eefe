"""Ray casts per second of the range-sensor kernel, for ensembles of 1, 100 and 1000 robots.

Each robot fires 48 beams (the XR4000's 24 infrared + 24 sonar, as single rays) into a
world of 50 wall segments; a second line adds three other robots per instance as circles,
and a third makes the 24 sonars 25-degree cones of 5 rays. A ray cast is one ray tested
against the whole world; the rate of ray/obstacle tests is printed alongside. Each figure
is the best of a few repeats (the machine is shared and noisy).

    python benchmarks/sensors.py
"""

from __future__ import annotations

import math
import time

import numpy as np

from hybridteam.world.sensors import RangeRing, cast


def best_of(repeats: int, fn) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    rng = np.random.default_rng(2024)
    walls = rng.uniform(-10.0, 10.0, (50, 4))
    ring = RangeRing(count=48, max_range=5.0, mount_radius=0.33, name="ir+sonar")
    ir = RangeRing(count=24, max_range=0.5, mount_radius=0.33, name="ir")
    sonar = RangeRing(
        count=24,
        max_range=5.0,
        min_range=0.15,
        mount_radius=0.33,
        half_angle=math.radians(12.5),
        rays_per_beam=5,
        name="sonar",
    )
    print("rays x obstacles                 m     ray casts/s    tests/s      per call")
    for m in (1, 100, 1000):
        poses = np.column_stack([rng.uniform(-8.0, 8.0, (m, 2)), rng.uniform(-3, 3, m)])
        others = np.concatenate(
            [rng.uniform(-8.0, 8.0, (m, 3, 2)), np.full((m, 3, 1), 0.33)], axis=2
        )
        origins, directions = ring.rays(poses)
        repeats = 20 if m < 1000 else 5
        cases = [
            ("48 rays x 50 walls", 48, 50, lambda o=origins, d=directions: cast(o, d, walls)),
            (
                "48 rays x 50 walls + 3 robots",
                48,
                53,
                lambda o=origins, d=directions, c=others: cast(o, d, walls, c),
            ),
            (
                "IR ring + sonar cones (144 rays)",
                144,
                53,
                lambda p=poses, c=others: (ir.read(p, walls, c), sonar.read(p, walls, c)),
            ),
        ]
        for label, rays, obstacles, fn in cases:
            seconds = best_of(repeats, fn)
            casts = m * rays / seconds
            print(
                f"{label:32s} {m:5d} {casts / 1e6:9.3f} M  {casts * obstacles / 1e6:9.1f} M"
                f"  {seconds * 1e3:9.3f} ms"
            )


if __name__ == "__main__":
    main()
