"""Benchmark models as functions (see ``shared/spec``)."""
from .sandwich import sandwich_2d, SANDWICH_2D

EXAMPLES = {"sandwich-2d": sandwich_2d}

__all__ = ["sandwich_2d", "SANDWICH_2D", "EXAMPLES"]
