"""Dense symmetric matrices: symmetrised and mirrored in place by row blocks (no
second matrix of their size), Cholesky solves without the finiteness scan. Shared by
the contact problem and the reduction."""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

__all__ = ["SYMMETRISE_ROWS", "cho_solved", "symmetrised", "mirror_triangle"]

#: Rows per block of :func:`symmetrised` (a block of 512 rows of a 6435-column
#: matrix is 26 MB).
SYMMETRISE_ROWS = 512


def cho_solved(cho, b) -> np.ndarray:
    """``A^{-1} b`` from ``cho = scipy.linalg.cho_factor(A)``, without the finiteness
    scan of the factor that :func:`scipy.linalg.cho_solve` makes by default.

    The factors passed here come from ``cho_factor`` of a checked finite matrix, so
    the scan (it reads the whole n x n factor) finds nothing. At n = 6,435 (sandwich-3d
    refine 2) a 12-column solve took 270 ms with the scan and 170 ms without (loaded
    machine, medians of 5); the tied modes make dozens of such solves. A NaN in ``b``
    still comes out as NaN."""
    return sla.cho_solve(cho, b, check_finite=False)


def symmetrised(A) -> np.ndarray:
    """``A`` overwritten by ``(A + A^T) / 2`` (square, C-contiguous), block by block
    so that no second matrix of its size is allocated; every entry is computed as
    ``(a_ij + a_ji) * 0.5``, the bits of ``0.5 * (A + A.T)``."""
    n = A.shape[0]
    for i in range(0, n, SYMMETRISE_ROWS):
        j = min(i + SYMMETRISE_ROWS, n)
        block = A[i:j, i:] + A[i:, i:j].T         # rows i..j, columns i..n
        block *= 0.5
        A[i:j, i:] = block
        A[i:, i:j] = block.T
    return A


def mirror_triangle(G, source="upper") -> np.ndarray:
    """Copy the ``source`` ("upper" or "lower") triangle of the square ``G`` onto the
    other one in place, by row blocks of :data:`SYMMETRISE_ROWS` (no full-size
    temporary)."""
    n = G.shape[0]
    for i in range(0, n, SYMMETRISE_ROWS):
        j = min(i + SYMMETRISE_ROWS, n)
        block = G[i:j, i:j]
        if source == "upper":
            G[j:, i:j] = G[i:j, j:].T
            lower = np.tril_indices(j - i, -1)
            block[lower] = block.T[lower]
        else:
            G[i:j, j:] = G[j:, i:j].T
            upper = np.triu_indices(j - i, 1)
            block[upper] = block.T[upper]
    return G
