"""Linear modes of the assembly with a chosen set of interface pairs tied.

Tied pairs share their DOFs (elimination, not penalty): the DOFs of the body-2
node of a tied pair are replaced by those of its body-1 partner. With a mortar
coupling a tied contact point is a multipoint constraint: the slave node's DOFs are
eliminated, ``u_slave = sum_k P_ik u_master_k`` per component.

One concern per module: :mod:`.linear` (:func:`linear_modes`, the entry point),
:mod:`.tied` (the tie transform, :class:`Modes`, the checks of rigid motions, the
factorised eigen solve, the probe), :mod:`.substructured` (the inverse through the
condensed bodies), :mod:`.eigen` (block Krylov shift-invert), :mod:`.leading` (the
loaded mode first, the others after it).
"""
from .eigen import block_shift_invert
from .leading import ModesToCome, leading_modes
from .linear import linear_modes
from .substructured import SubstructuredInverse, identity_rows, substructured_inverse
from .tied import (LANCZOS_MEMORY_SHARE, MAX_MODES, RIGID_TOL, FREE_SHIFT_RTOL, Modes,
                   check_n_modes, free_shift, mode_tip, nonrigid_part, probe_vector,
                   stacked, tie_transform)

__all__ = ["linear_modes", "leading_modes", "ModesToCome", "Modes", "tie_transform", "stacked", "mode_tip",
           "probe_vector", "nonrigid_part", "free_shift", "check_n_modes",
           "block_shift_invert", "SubstructuredInverse", "substructured_inverse",
           "identity_rows", "MAX_MODES", "RIGID_TOL", "FREE_SHIFT_RTOL",
           "LANCZOS_MEMORY_SHARE"]
