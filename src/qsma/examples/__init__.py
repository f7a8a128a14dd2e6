"""Benchmark and example models as functions (docs/validation.md describes each)."""
from .bolted import lap_2d_bolted, lap_3d_bolted, sandwich_2d_bolted
from .brb import BRB, brb
from .held import lap_2d_cantilever, lap_2d_free
from .lap import LAP_2D, LAP_3D, lap_2d, lap_3d
from .sandwich import sandwich_2d, sandwich_3d, SANDWICH_2D, SANDWICH_3D
from .stack import STACK_2D, stack_2d
from .files import copy_examples, example_dir, example_file, example_files

EXAMPLES = {"sandwich-2d": sandwich_2d, "sandwich-3d": sandwich_3d, "lap-2d": lap_2d,
            "lap-3d": lap_3d, "stack-2d": stack_2d, "lap-2d-cantilever": lap_2d_cantilever,
            "lap-2d-free": lap_2d_free, "lap-2d-bolted": lap_2d_bolted,
            "lap-3d-bolted": lap_3d_bolted, "sandwich-2d-bolted": sandwich_2d_bolted,
            "brb": brb}

__all__ = ["sandwich_2d", "sandwich_3d", "lap_2d", "lap_3d", "SANDWICH_2D", "SANDWICH_3D",
           "LAP_2D", "LAP_3D", "STACK_2D", "stack_2d", "EXAMPLES", "lap_2d_cantilever",
           "lap_2d_free", "lap_2d_bolted", "lap_3d_bolted", "sandwich_2d_bolted", "BRB", "brb",
           "example_file", "example_files", "example_dir", "copy_examples"]
