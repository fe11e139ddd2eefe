"""hybridteam: teams of robots as hybrid systems."""

__version__ = "0.1.0"
