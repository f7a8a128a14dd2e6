"""Benchmark and example models as functions (docs/validation.md describes each)."""
from .lap import LAP_2D, LAP_3D, lap_2d, lap_3d
from .sandwich import sandwich_2d, sandwich_3d, SANDWICH_2D, SANDWICH_3D
from .stack import STACK_2D, stack_2d

EXAMPLES = {"sandwich-2d": sandwich_2d, "sandwich-3d": sandwich_3d, "lap-2d": lap_2d,
            "lap-3d": lap_3d, "stack-2d": stack_2d}

__all__ = ["sandwich_2d", "sandwich_3d", "lap_2d", "lap_3d", "SANDWICH_2D", "SANDWICH_3D",
           "LAP_2D", "LAP_3D", "STACK_2D", "stack_2d", "EXAMPLES"]
