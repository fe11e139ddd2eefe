"""Robot models as named presets (Labmate, XR4000, Scout, omni), declared in YAML.

Framework level: a preset is plain data about a body (plant, limits, footprint, sensors,
manipulator); what a robot *does* belongs to mode libraries.
"""

from hybridteam.robots.presets import PresetErrors, RobotPreset, load_presets, resolve

__all__ = ["PresetErrors", "RobotPreset", "load_presets", "resolve"]
