"""The ``"splu"`` backend (scipy only): ``X = K_EE^-1 K_EC`` by a dense multi-RHS
solve in column blocks of bounded memory, ``Kc = K_CC - K_EC^T X``."""
from __future__ import annotations

import time

import numpy as np

from ..._infra.threads import one_blas_thread
from .registry import PIVOT_RATIO_MIN, SchurParts, _blocks, register_backend
from .superlu import _factorised_EE, _superlu_solver

#: Memory bound of one dense block of ``K_EE^-1 K_EC`` columns in the ``"splu"`` backend.
SPLU_BLOCK_BYTES = 128 * 2**20


@register_backend("splu")
def _schur_splu(K, C, E) -> SchurParts:
    """``Kc = K_CC - K_EC^T (K_EE^-1 K_EC)``, the solve in column blocks of at most
    :data:`SPLU_BLOCK_BYTES`."""
    t0 = time.perf_counter()
    K_EE, K_EC, Kc = _blocks(K, C, E)
    lu, ratio = _factorised_EE(K_EE)
    t1 = time.perf_counter()
    if ratio > PIVOT_RATIO_MIN:
        width = max(1, SPLU_BLOCK_BYTES // (8 * len(E)))
        for j in range(0, len(C), width):
            with one_blas_thread():
                X = lu.solve(np.asfortranarray(K_EC[:, j:j + width].toarray()))
            Kc[:, j:j + width] -= K_EC.T @ X
    t2 = time.perf_counter()
    return SchurParts(Kc, _superlu_solver(lu), ratio,
                      {"factorization": t1 - t0, "schur": t2 - t1})
