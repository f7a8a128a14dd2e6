"""Sparse SPD solves outside the condensation (the shift-invert of the tied
eigenproblem, a body's ``K_EE`` factorised again on another process)."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ...errors import InputError
from .ordering import nested_dissection
from .pardiso import _Pardiso, _pardiso_solver
from .registry import PIVOT_RATIO_MIN, SCHUR_BACKENDS
from .superlu import _superlu, _superlu_solver

def spd_solver(A, *, backend="auto"):
    """``solve(b) = A^-1 b`` for a sparse symmetric positive definite ``A``: PARDISO
    (nested dissection) when ``pypardiso`` is installed and ``backend`` is ``"auto"`` or
    ``"pardiso"``; else SuperLU without pivoting, on ``A`` ordered by METIS nested
    dissection when ``pymetis`` is installed (``"auto"`` or ``"metis_superlu"``), by
    SuperLU's MMD otherwise. Used for the shift-invert of the tied eigenproblem. Raises
    :class:`InputError` if ``A`` is singular or not positive definite."""
    A = sp.csr_matrix(A)
    use_pardiso = backend in ("auto", "pardiso") and SCHUR_BACKENDS["pardiso"].available
    if use_pardiso:
        f = _Pardiso(A)
        try:
            f.call(12, np.zeros(A.shape[0]), np.zeros(A.shape[0]))
        except InputError as exc:
            raise InputError(f"matrix is singular or not positive definite ({exc})") from exc
        return _pardiso_solver(f)
    use_metis = (backend in ("auto", "metis_superlu")
                 and SCHUR_BACKENDS["metis_superlu"].available)
    p = nested_dissection(A) if use_metis else None
    lu, ratio, exc = _superlu(A if p is None else A[p][:, p],
                              ordering="MMD_AT_PLUS_A" if p is None else "NATURAL")
    if lu is None or ratio <= PIVOT_RATIO_MIN:
        raise InputError(f"matrix is singular or not positive definite "
                         f"(smallest pivot ratio {ratio:.3g})") from exc
    solve = _superlu_solver(lu)
    if p is None:
        return solve

    def permuted(b):
        x = np.empty_like(b, dtype=float)
        x[p] = solve(np.asarray(b, dtype=float)[p])
        return x
    return permuted
