"""Robot logs in and out: a run as a rosbag2 (:mod:`~hybridteam.logs.export`), a rosbag2 as a run
(:mod:`~hybridteam.logs.bag`), a team's requirements checked on either
(:mod:`~hybridteam.logs.check`), and either replayed into its team and compared with it
(:mod:`~hybridteam.logs.conformance`).

The bag format is handled by ``rosbags`` (pure Python, no ROS installation), an optional dependency:
``pip install 'hybridteam[logs]'``. Topic names, message types, frames and the time epoch are
documented in ``docs/logs.md`` and defined once in :mod:`~hybridteam.logs.topics`.
"""

from __future__ import annotations

INSTALL_HINT = "this needs rosbags: pip install 'hybridteam[logs]'"


class LogError(Exception):
    """A log that cannot be read or written: one line naming the file, topic and time."""


def require_rosbags() -> None:
    """Raise :class:`LogError` with the install line when ``rosbags`` is missing."""
    try:
        import rosbags.rosbag2  # noqa: F401
    except ImportError:
        raise LogError(INSTALL_HINT) from None
