"""One agent's ``deploy:`` settings: where its robot is when it runs on one over ROS 2.

The team file's ``deploy:`` section maps agent names to these settings (docs/live.md); a
simulation ignores it, and ``hybridteam live --plant ros2`` drives each hosted agent's
robot through them (:mod:`hybridteam.live.ros2_plant`). Plain data here, checked where it is
read, so that ``validate`` reports a bad setting at its line without ROS installed::

    cmd_vel: /scout1/cmd_vel   # required: where Twist commands are published
    odom: /scout1/odom         # required: where Odometry is read
    scan: /scout1/scan         # optional: where LaserScan is read
    frame: odom                # optional, default "odom": the frame poses must be given in
    timeout: 2.0               # optional, default 2 s: how long odometry may be silent

Topics are given by their full names (a relative name would resolve against the plant's own
node, not where the robot's driver publishes).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from hybridteam.errors import DocPath, ModelError, did_you_mean

#: a topic's full name: relative ones would resolve against the plant node's namespace
_TOPIC = re.compile(r"(/[A-Za-z_]([A-Za-z0-9]|_(?!_))*)+")

_KEYS = ("cmd_vel", "odom", "scan", "frame", "timeout")


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
                raise ModelError((*path, key), f"unknown deploy setting {key!r}",
                                 hint=did_you_mean(str(key), _KEYS), at_key=True)
        for key in ("cmd_vel", "odom"):
            if key not in config:
                raise ModelError(path, f"missing {key!r}: the robot's "
                                 + ("Twist command topic" if key == "cmd_vel"
                                    else "Odometry topic"))
        for key in ("cmd_vel", "odom", "scan"):
            value = config.get(key)
            if key in config and not (isinstance(value, str) and _TOPIC.fullmatch(value)):
                raise ModelError((*path, key), f"expected a topic's full name (/name/name..., "
                                 "each name letters, digits and single underscores, not "
                                 f"starting with a digit), got {value!r}")
        frame = config.get("frame", "odom")
        if not (isinstance(frame, str) and frame):
            raise ModelError((*path, "frame"), f"expected a frame name, got {frame!r}")
        timeout = config.get("timeout", 2.0)
        if (isinstance(timeout, bool) or not isinstance(timeout, int | float)
                or not 0 < timeout < math.inf):
            raise ModelError((*path, "timeout"),
                             f"expected a number of seconds > 0, got {timeout!r}")
        return cls(config["cmd_vel"], config["odom"], config.get("scan"), frame,
                   float(timeout))
