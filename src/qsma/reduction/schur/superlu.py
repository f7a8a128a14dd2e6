"""SuperLU (scipy) as the backends use it: factorisations without pivoting of SPD
matrices with their smallest pivot ratio, and multi-RHS solves split over threads by
columns (:func:`solved_by_columns`)."""
from __future__ import annotations

import threading

import numpy as np
import scipy.sparse.linalg as spla

from ..._infra.threads import one_blas_thread, solve_threads
from ...errors import InputError

def _superlu(A, ordering="MMD_AT_PLUS_A"):
    """LU of the SPD matrix ``A`` without row pivoting (symmetric fill-reducing
    ordering ``ordering``, by default MMD on A + A^T), and its smallest pivot ratio."""
    try:
        with one_blas_thread():
            lu = spla.splu(A.tocsc(), permc_spec=ordering, diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
    except RuntimeError as exc:      # "Factor is exactly singular"
        return None, -np.inf, exc
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return lu, -np.inf, None     # pivoting happened: not SPD
    pivots = lu.U.diagonal()[lu.perm_c]          # pivot of original column k
    _drop_extracted_factors(lu)
    return lu, float(np.min(pivots / A.diagonal())), None


def _drop_extracted_factors(lu):
    """Empty the CSC copies of L and U that scipy's ``SuperLU`` builds at the first
    access of ``lu.L`` or ``lu.U`` and then keeps for the object's lifetime (both at
    once: 12 bytes an entry, 1.55 GB for one 3D refine-2 body, on top of SuperLU's own
    factor). The copies become empty matrices of the same shape; ``lu.solve`` does not
    use them. Call only after one of them has been read (else this builds them)."""
    for copy in (lu.L, lu.U):
        copy.data = np.zeros(0, dtype=copy.data.dtype)
        copy.indices = np.zeros(0, dtype=copy.indices.dtype)
        copy.indptr = np.zeros(copy.shape[1] + 1, dtype=copy.indptr.dtype)


#: Fewest columns a thread of :func:`solved_by_columns` is given. Measured on the
#: sandwich-3d refine-1 factor (15,810 DOFs, one BLAS thread): 8 columns take 41 ms
#: serially and 52 ms as two threads of 4 (the two threads share the reading of the
#: factor), 12 columns 71 ms and 45 ms as two of 6 (docs/performance.md, "Solve threads").
SOLVE_MIN_COLUMNS = 6


def solved_by_columns(solve, b, threads=None) -> np.ndarray:
    r"""``solve(b)`` for a multi-RHS ``solve`` (a sparse factor's triangular solves),
    with the columns of ``b`` split into ``t`` consecutive blocks solved by ``t``
    threads at once:

    .. math:: X = [\,\mathrm{solve}(B_1), \dots, \mathrm{solve}(B_t)\,],
              \qquad B = [B_1, \dots, B_t] .

    The columns of a solve are independent, so the result has the bits of the serial
    solve of the same blocks. SuperLU (``nrhs >= 2``) works on the columns with BLAS
    ``trsm`` and ``gemm``, whose kernels (scipy's OpenBLAS 0.3.30, one BLAS thread;
    Haswell, SandyBridge, Zen, Prescott) treat columns in pairs and a last odd column
    by another path (a different rounding, measured ~5e-16 relative): the blocks
    therefore start at even offsets, so that every column keeps its partner and the
    threaded solve has the bits of the serial one (tests/test_linalg.py). OpenBLAS's
    Nehalem kernel (older CPUs, virtual machines without AVX) rounds a column with
    wider groups: there the threaded solve differs from the serial one by round-off
    (~1e-16 relative; tied modes 3e-13), so results can depend on the thread count
    at that level; ``QSMA_SOLVE_THREADS=1`` gives the serial bits. With several BLAS
    threads the bits of a solve depend on its width (OpenBLAS splits the columns among
    its threads), so the blocks are solved with
    BLAS limited to one thread (:func:`qsma._infra.threads.one_blas_thread`), which is also
    the fast setting: SuperLU calls BLAS on small supernode blocks, where OpenBLAS
    threads spin (a 12-column solve at sandwich-3d refine 1: 506 ms with two BLAS
    threads, 66 ms with one). The threads pay only where the solve releases the GIL
    (scipy's SuperLU does).

    Parameters
    ----------
    solve : callable on (n, k) arrays returning (n, k) arrays
    b : (n,) or (n, k) array
    threads : thread count (:func:`qsma._infra.threads.solve_threads`: validated, default
        from the environment or ``min(2, cores)``); ``t = min(threads,
        k // SOLVE_MIN_COLUMNS)`` blocks, one block (a plain call) below that.
    """
    t = min(solve_threads(threads), b.shape[1] // SOLVE_MIN_COLUMNS if b.ndim == 2 else 1)
    with one_blas_thread():
        return solve(b) if t <= 1 else _threaded(solve, b, t)


def _threaded(solve, b, t):
    """:func:`solved_by_columns` on ``t >= 2`` threads."""
    edges = 2 * np.round(np.linspace(0, b.shape[1] / 2, t + 1)).astype(int)
    edges[-1] = b.shape[1]                       # even offsets: see the docstring
    blocks = [b[:, i:j] for i, j in zip(edges[:-1], edges[1:])]
    out = [None] * t
    errors = []

    def work(k):
        try:
            out[k] = solve(blocks[k])
        except BaseException as exc:            # re-raised in the calling thread
            errors.append(exc)

    workers = [threading.Thread(target=work, args=(k,), daemon=True) for k in range(1, t)]
    for w in workers:
        w.start()
    work(0)
    for w in workers:
        w.join()
    if errors:
        raise errors[0]
    return np.hstack(out)


def _superlu_solver(lu):
    def whole(b):
        return lu.solve(b if b.ndim == 1 else np.asfortranarray(b))

    def solve(b):
        return solved_by_columns(whole, b)
    return solve


def _factorised_EE(K_EE):
    lu, ratio, exc = _superlu(K_EE)
    if lu is None:
        raise InputError(f"K_EE is singular ({exc}); the body is not held against "
                         f"rigid-body motion apart from its interface: add clamps") from exc
    return lu, ratio
