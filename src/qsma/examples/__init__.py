"""Benchmark models as functions (see ``shared/spec``)."""
from .sandwich import sandwich_2d, sandwich_3d, SANDWICH_2D, SANDWICH_3D

EXAMPLES = {"sandwich-2d": sandwich_2d, "sandwich-3d": sandwich_3d}

__all__ = ["sandwich_2d", "sandwich_3d", "SANDWICH_2D", "SANDWICH_3D", "EXAMPLES"]
