"""Benchmark and example models as functions (docs/validation.md describes each)."""
import math

from ..errors import InputError
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
           "check_refine", "run_bytes", "example_file", "example_files", "example_dir",
           "copy_examples"]


#: Peak memory of a run per degree of freedom, measured on the preparation (assembly
#: and condensation, the larger stages; ``qsma._infra.resources.peak_memory_mb`` over the
#: imports): sandwich-2d refine 4 / 8, 65604 / 258180 DOFs: 2.2 / 2.4 kB per DOF,
#: about 140 log2(n) bytes (nested-dissection fill of a 2D mesh); sandwich-3d refine
#: 1 / 2 (docs/performance.md): 9.3 / 14.5 kB per DOF, about 240 n^(1/3) bytes.
RUN_BYTES_PER_DOF = {2: lambda n: 140.0 * math.log2(max(n, 2)),
                     3: lambda n: 240.0 * n ** (1.0 / 3.0)}


def run_bytes(n_dofs: int, dim: int) -> float:
    """Estimated peak memory of a run of a model of ``n_dofs`` DOFs in ``dim`` D."""
    return n_dofs * RUN_BYTES_PER_DOF[dim](n_dofs)


def check_refine(name: str, refine) -> None:
    """Refuse a refinement of example ``name`` whose run would not fit in the free memory
    (``--refine 100`` allocated 4.7 and 29.7 GiB before failing), from its size at refine
    1 (DOFs grow as ``refine^dim``), before the mesh is made."""
    from .._infra.resources import free_memory
    if not isinstance(refine, int) or isinstance(refine, bool) or refine < 1:
        raise InputError(f"--refine must be a positive integer, got {refine!r}")
    free = free_memory()
    if refine == 1 or free is None:
        return
    base = EXAMPLES[name](refine=1)
    dofs = lambda r: base.n_dofs * r ** base.dim
    if run_bytes(dofs(refine), base.dim) <= free:
        return
    most = 1
    while run_bytes(dofs(most + 1), base.dim) <= free:
        most += 1
    raise InputError(f"--refine {refine}: {name} would have about {dofs(refine):.3g} DOFs "
                     f"and need about {run_bytes(dofs(refine), base.dim) / 2**30:.1f} GiB, "
                     f"more than the free memory ({free / 2**30:.1f} GiB); use --refine "
                     f"{most} or less")
