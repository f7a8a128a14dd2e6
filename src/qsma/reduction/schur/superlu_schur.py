"""The ``"superlu_schur"`` backend (scipy only): ``K`` ordered ``[E by SuperLU's MMD,
C last]`` and factorised without pivoting, so that ``Kc = U_CC^T D_C^-1 U_CC``."""
from __future__ import annotations

import time

import numpy as np
import scipy.sparse.linalg as spla

from ..._infra.threads import one_blas_thread
from .registry import PIVOT_RATIO_MIN, SchurParts, register_backend
from .splu import _schur_splu
from .superlu import _factorised_EE, _superlu_solver

@register_backend("superlu_schur")
def _schur_superlu_partial(K, C, E) -> SchurParts:
    r"""Partial factorisation with SuperLU: ``P K P^T = L U`` for the ordering
    ``[E (MMD of K_EE), C]`` without pivoting; the trailing block gives
    ``Kc = L_CC U_CC = U_CC^T D_C^{-1} U_CC`` (``L = U^T D^{-1}`` for symmetric K).
    A second LU, of ``K_EE`` alone, supplies the ordering and the solver."""
    t0 = time.perf_counter()
    K_EE = K[E][:, E].tocsc()
    lu, ratio = _factorised_EE(K_EE)
    t1 = time.perf_counter()
    if not ratio > PIVOT_RATIO_MIN:
        return SchurParts(np.zeros((len(C), len(C))), None, ratio, {})
    order = np.concatenate([E[np.argsort(lu.perm_c)], C])
    Kc = _superlu_trailing_schur(K[order][:, order], len(E))
    if Kc is None:                   # SuperLU's postorder moved C: use the dense solve
        return _schur_splu(K, C, E)
    t2 = time.perf_counter()
    return SchurParts(Kc, _superlu_solver(lu), ratio,
                      {"factorization": t1 - t0, "schur": t2 - t1})


def _superlu_trailing_schur(Kp, nE):
    """Schur complement of the leading ``nE`` block of ``Kp`` from its LU in the given
    order (``None`` if SuperLU's elimination-tree postorder mixed the two blocks)."""
    n = Kp.shape[0]
    try:
        with one_blas_thread():
            lu = spla.splu(Kp.tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
    except RuntimeError:
        return None
    pc = lu.perm_c
    if not np.array_equal(lu.perm_r, pc) or np.any(pc[nE:] < nE):
        return None
    U = lu.U.tocsc()[:, nE:][nE:].toarray()      # trailing rows/cols, SuperLU order
    S = U.T @ (U / np.diag(U)[:, None])
    pos = pc[nE:] - nE                            # C-local i sits at trailing pos[i]
    return S[np.ix_(pos, pos)]
