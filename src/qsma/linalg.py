r"""Static condensation of a sparse SPD stiffness onto a set of DOFs.

For ``K`` (n x n, sparse, symmetric positive definite), interface DOFs ``C`` and
the rest ``E = np.setdiff1d(np.arange(n), C)`` (sorted)::

    Kc = K_CC - K_CE K_EE^-1 K_EC            (the Schur complement of K_EE)
    solver(b) = K_EE^-1 b                    (recovery, condensed loads)

Several backends compute the same two objects; :data:`SCHUR_BACKENDS` maps a
name to its function and ``backend="auto"`` takes the first available one of
:data:`AUTO_ORDER` (fastest first, measured by ``benchmarks/bench_schur.py``;
the numbers are in ``docs/schur.md``):

``"pardiso"``
    Intel MKL PARDISO through ``pypardiso``'s ``mkl_rt``: nested-dissection
    ordering and the Schur complement computed during the factorisation
    (``iparm(36) = 1``), plus a plain Cholesky of ``K_EE`` for the solver.
``"multifrontal"``
    our own Cholesky of ``K_EE`` with dense fronts on a METIS separator tree of its
    node graph (:mod:`qsma.multifrontal`, ``pymetis``): the interface rows ride along
    in every front and their updates sum to ``K_CE K_EE^-1 K_EC``; the factor (one
    triangle) solves with ``K_EE`` (the default for 3D solids without PARDISO).
``"metis_superlu"``
    METIS nested dissection of ``K_EE`` (``pymetis``) on its node graph and one SuperLU
    factorisation of the bordered matrix ``[[K_EE, K_EC], [0, I]]`` in that order,
    without pivoting: ``Kc = K_CC - U_EC^T D^-1 U_EC`` by blocked BLAS products, and
    the same factor solves with ``K_EE`` (the default for 2D and scalar problems
    without PARDISO).
``"cholmod"``
    CHOLMOD (supernodal Cholesky, from the ``cvxopt`` wheel) of ``K`` ordered
    ``[E by AMD, C last]``: ``K = L L^T`` with ``Kc = L_CC L_CC^T``.
``"superlu_schur"``
    scipy only, the same partial factorisation with SuperLU: ``K`` ordered
    ``[E by SuperLU's MMD, C last]`` factorised without pivoting, so that
    ``Kc = U_CC^T D_C^-1 U_CC``.
``"splu"``
    scipy only, the former method: ``X = K_EE^-1 K_EC`` by a dense multi-RHS
    solve (in column blocks of bounded memory), ``Kc = K_CC - K_EC^T X``.

Every backend checks that ``K_EE`` is positive definite through its pivots:
the smallest pivot relative to its diagonal entry, ``min_i d_i / (K_EE)_ii``,
must exceed :data:`PIVOT_RATIO_MIN`; otherwise :class:`~qsma.errors.InputError`
(a body not held against rigid-body motion apart from the interface).
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
import importlib.util
import threading
import time
import weakref

import numpy as np
import scipy.sparse as sp
import scipy.linalg as sla
import scipy.sparse.linalg as spla
from scipy.linalg import blas as sla_blas

from ._threads import one_blas_thread, solve_threads
from .errors import AnalysisError, InputError

#: Smallest accepted ``d_i / (K_EE)_ii`` over the pivots ``d_i`` of ``K_EE``. It is
#: ``>= 1 / cond`` of the Jacobi-scaled ``K_EE`` when that is SPD. The sandwich-2d
#: beams and the 3D block of benchmarks/bench_schur.py measure 2e-4 .. 5e-2, depending
#: on the backend's ordering. A rigid-body mode leaves a pivot at round-off level:
#: SuperLU measures -8e-14 .. -4e-14 on the free sandwich beam of
#: tests/test_linalg.py, where CHOLMOD and PARDISO stop at a non-positive pivot.
PIVOT_RATIO_MIN = 1e-12

#: Relative asymmetry ``max|K - K^T| / max|K|`` accepted by :func:`schur_complement`.
SYMMETRY_TOL = 1e-10

#: Memory bound of one dense block of ``K_EE^-1 K_EC`` columns in the ``"splu"`` backend.
SPLU_BLOCK_BYTES = 128 * 2**20

#: name -> :class:`SchurBackend`, filled by :func:`register_backend`.
SCHUR_BACKENDS: dict = {}

#: Order in which ``backend="auto"`` tries the backends (fastest first, docs/schur.md);
#: ``multifrontal`` only where :func:`suits_multifrontal` says so.
AUTO_ORDER = ("pardiso", "multifrontal", "metis_superlu", "cholmod", "superlu_schur",
              "splu")

#: Fewest DOFs per node on average (supervariables of ``K``) for which ``auto`` takes
#: ``multifrontal``: 3D solids (3 DOFs per node) yes, 2D (2) and scalar problems (1)
#: no. Measured with benchmarks/bench_schur.py, one BLAS thread, CPU seconds of one
#: body against ``metis_superlu``: 3D blocks 0.78 s against 1.05 s (15,810 DOFs) and
#: 14.6 s against 34.4 s (110,484 DOFs, 1.4 GB against 3.1 GB peak); the sandwich-2d
#: beams 0.041 against 0.017 s (2,232 DOFs), 0.65 against 0.33 s (32,736) and 2.8
#: against 1.7 s (128,960): in 2D the separators are short, SuperLU's supernodes do
#: well and the fronts' Python work does not pay (docs/schur.md).
MULTIFRONTAL_MIN_DOFS_PER_NODE = 2.5


def suits_multifrontal(K) -> bool:
    """Whether ``auto`` condenses ``K`` (sparse, canonical CSR) with ``multifrontal``:
    its rows average at least :data:`MULTIFRONTAL_MIN_DOFS_PER_NODE` per supervariable
    (:func:`supervariables`, the DOFs of a node)."""
    n = K.shape[0]
    if n == 0:
        return False
    groups = int(supervariables(K)[-1]) + 1
    return n >= MULTIFRONTAL_MIN_DOFS_PER_NODE * groups


@dataclass(frozen=True)
class SchurBackend:
    """A registered way to compute ``(Kc, K_EE^-1)``; ``requires`` names the optional
    Python package it imports (``None``: numpy/scipy only)."""

    name: str
    function: object
    requires: str | None = None

    @property
    def available(self) -> bool:
        return self.requires is None or importlib.util.find_spec(self.requires) is not None


@dataclass(frozen=True)
class SchurParts:
    """What a backend returns: ``Kc`` in the caller's ``C`` order (not yet
    symmetrised), ``solve`` with ``K_EE^-1`` on (n_E,) or (n_E, k) arrays, the
    smallest pivot ratio of ``K_EE`` and a few named times (s)."""

    Kc: np.ndarray
    solve: object
    min_pivot_ratio: float
    timings: dict = field(default_factory=dict)


def ee_rhs(b, n) -> np.ndarray:
    """``b`` as a float array of shape ``(n,)`` or ``(n, k)`` for a ``K_EE`` solve;
    :class:`InputError` naming the shape otherwise."""
    b = np.asarray(b, dtype=float)
    if b.ndim not in (1, 2) or b.shape[0] != n:
        raise InputError(f"K_EE solve: right-hand side must have shape ({n},) or "
                         f"({n}, k), got {b.shape}")
    return b


@dataclass(frozen=True, eq=False)
class EESolver:
    r"""``x = K_EE^-1 b`` for ``b`` of shape (n_E,) or (n_E, k), E in sorted order
    (``E = np.setdiff1d(np.arange(n), C)``); returns an array of ``b``'s shape.

    Attributes
    ----------
    E : positions of the E DOFs in K
    backend : name of the backend that factorised ``K_EE``
    min_pivot_ratio : ``min_i d_i / (K_EE)_ii`` over the pivots (positive definite check)
    timings : seconds spent per stage of :func:`schur_complement`
    """

    E: np.ndarray
    backend: str
    min_pivot_ratio: float
    timings: dict
    _solve: object = field(repr=False)

    @property
    def n(self) -> int:
        return len(self.E)

    def __call__(self, b) -> np.ndarray:
        b = ee_rhs(b, self.n)
        return b if b.size == 0 else self._solve(b)

    def __repr__(self):
        return (f"EESolver(n={self.n}, backend={self.backend!r}, "
                f"min_pivot_ratio={self.min_pivot_ratio:.3g})")


def register_backend(name: str, *, requires: str | None = None):
    """Decorator: register ``function(K, C, E) -> SchurParts`` under ``name``."""
    def decorate(function):
        SCHUR_BACKENDS[name] = SchurBackend(name, function, requires)
        return function
    return decorate


def available_backends() -> list:
    """Names of the registered backends whose optional package is installed."""
    return [name for name, b in SCHUR_BACKENDS.items() if b.available]


def schur_complement(K, C, *, backend: str = "auto"):
    r"""Condense the SPD matrix ``K`` onto the DOFs ``C``.

    Parameters
    ----------
    K : scipy sparse (n, n), symmetric positive definite (Dirichlet DOFs removed)
    C : int array of distinct positions in ``0..n-1``; the rows/columns of ``Kc``
        follow this order
    backend : ``"auto"`` or a key of :data:`SCHUR_BACKENDS`

    Returns
    -------
    Kc : (|C|, |C|) dense symmetric ``K_CC - K_CE K_EE^-1 K_EC`` (symmetrised,
        ``(Kc + Kc^T) / 2``)
    solver : :class:`EESolver`, ``solver(b) = K_EE^-1 b`` with the E DOFs in the order
        ``E = np.setdiff1d(np.arange(n), C)``

    Raises
    ------
    InputError
        bad ``K`` or ``C``, unknown or unavailable backend, or ``K_EE`` not positive
        definite (smallest pivot ratio below :data:`PIVOT_RATIO_MIN`).
    """
    K, C, E = _validated(K, C)
    name = _chosen_backend(backend, K)
    t0 = time.perf_counter()
    parts = SCHUR_BACKENDS[name].function(K, C, E)
    _check_pivots(parts.min_pivot_ratio, name)
    Kc = symmetrised(np.ascontiguousarray(parts.Kc, dtype=float))   # in place
    if not np.all(np.isfinite(Kc)):
        raise AnalysisError(f"Schur complement ({name}) has NaN/Inf entries", partial=Kc)
    timings = {**parts.timings, "total": time.perf_counter() - t0}
    return Kc, EESolver(E, name, parts.min_pivot_ratio, timings, parts.solve)


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


def _validated(K, C):
    if not sp.issparse(K) or K.ndim != 2 or K.shape[0] != K.shape[1]:
        raise InputError(f"K must be a square scipy sparse matrix, got "
                         f"{type(K).__name__} of shape {getattr(K, 'shape', None)}")
    n = K.shape[0]
    C = np.asarray(C)
    if C.ndim != 1 or not np.issubdtype(C.dtype, np.integer):
        raise InputError(f"C must be a 1-D integer array, got dtype {C.dtype} and shape "
                         f"{C.shape}")
    if len(C) == 0 or len(C) >= n:
        raise InputError(f"C must hold between 1 and n - 1 = {n - 1} DOFs, got {len(C)}")
    if C.min() < 0 or C.max() >= n:
        raise InputError(f"C holds positions outside 0..{n - 1}: {C.min()}..{C.max()}")
    if len(np.unique(C)) != len(C):
        raise InputError("C holds repeated positions")
    K = sp.csr_matrix(K, dtype=float)             # shares the caller's arrays where
    if not K.has_canonical_format:                # it can: not modified below
        K = K.copy()
        K.sum_duplicates()
    scale = abs(K).max()
    if not np.isfinite(scale) or scale == 0:
        raise InputError(f"K must have finite, not all zero entries (max |K| = {scale})")
    asym = abs(K - K.T).max() / scale
    if asym > SYMMETRY_TOL:
        raise InputError(f"K must be symmetric: max|K - K^T| / max|K| = {asym:.3g} > "
                         f"{SYMMETRY_TOL}")
    diagonal = K.diagonal()
    negative = np.flatnonzero(diagonal < 0)
    if len(negative):                 # the LU pivot ratios d_i / a_i would not see it
        i = int(negative[0])
        raise InputError(f"K is singular or not positive definite: diagonal entry "
                         f"K[{i}, {i}] = {diagonal[i]:.3g} < 0 ({len(negative)} such "
                         f"entries); a stiffness matrix has a positive diagonal: check the "
                         f"material constants and the elements' orientation")
    return K, C.astype(np.int64), np.setdiff1d(np.arange(n), C)


def _chosen_backend(backend, K=None):
    """The backend to run: ``backend`` itself (checked), or for ``"auto"`` the first
    available one of :data:`AUTO_ORDER` (``multifrontal`` only if
    :func:`suits_multifrontal` of ``K``)."""
    if backend == "auto":
        return next(n for n in AUTO_ORDER if n in SCHUR_BACKENDS and SCHUR_BACKENDS[n].available
                    and (n != "multifrontal" or (K is not None and suits_multifrontal(K))))
    if backend not in SCHUR_BACKENDS:
        raise InputError(f"unknown Schur backend {backend!r}; registered: "
                         f"{sorted(SCHUR_BACKENDS)}")
    b = SCHUR_BACKENDS[backend]
    if not b.available:
        raise InputError(f"Schur backend {backend!r} needs the package {b.requires!r}, "
                         f"which is not installed; available: {available_backends()}")
    return backend


def _check_pivots(ratio, name):
    if not ratio > PIVOT_RATIO_MIN:          # also catches NaN
        raise InputError(
            f"K_EE is singular or not positive definite (backend {name!r}: smallest pivot "
            f"/ diagonal = {ratio:.3g}, expected > {PIVOT_RATIO_MIN}); the body is not "
            f"held against rigid-body motion apart from its interface: add clamps")


def _blocks(K, C, E):
    """``K_EE`` (csc), ``K_EC`` (csc) and dense ``K_CC``."""
    KE = K[E]
    return KE[:, E].tocsc(), KE[:, C].tocsc(), K[C][:, C].toarray()


# ----------------------------------------------------------------------------------
# SuperLU (scipy only)

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
#: factor), 12 columns 71 ms and 45 ms as two of 6 (docs/performance.md).
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
    BLAS limited to one thread (:func:`qsma._threads.one_blas_thread`), which is also
    the fast setting: SuperLU calls BLAS on small supernode blocks, where OpenBLAS
    threads spin (a 12-column solve at sandwich-3d refine 1: 506 ms with two BLAS
    threads, 66 ms with one). The threads pay only where the solve releases the GIL
    (scipy's SuperLU does).

    Parameters
    ----------
    solve : callable on (n, k) arrays returning (n, k) arrays
    b : (n,) or (n, k) array
    threads : thread count (:func:`qsma._threads.solve_threads`: validated, default
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


# ----------------------------------------------------------------------------------
# METIS nested dissection + SuperLU, one factorisation (numpy/scipy + pymetis)

#: Columns of ``L_CE`` per dense block of the Schur update in ``"metis_superlu"``.
SCHUR_UPDATE_COLUMNS = 256


def nested_dissection(A) -> np.ndarray:
    r"""Fill-reducing permutation of the symmetric sparse ``A`` by METIS nested
    dissection (``pymetis``): ``A[p][:, p]`` factorises with little fill.

    METIS orders the quotient graph of the supervariables (:func:`supervariables`:
    runs of consecutive rows with the same pattern, the ``dim`` DOFs of a node in an
    FE matrix): vertices ``g``, an edge ``g - h`` where ``A`` couples them. The
    permutation lists the groups in METIS's order, each group's rows consecutively.
    On a 3D body of 15,810 DOFs (sandwich-3d refine 1) this is 7x faster than METIS
    on the DOF graph, with the same fill (docs/performance.md)."""
    import pymetis
    group, G = node_graph(A)
    n_groups = G.shape[0]
    if G.nnz == 0:
        return np.arange(A.shape[0])
    order, _ = pymetis.nested_dissection(pymetis.CSRAdjacency(G.indptr, G.indices))
    rank = np.empty(n_groups, dtype=np.int64)
    rank[np.asarray(order, dtype=np.int64)] = np.arange(n_groups)
    return np.argsort(rank[group], kind="stable")


def node_graph(A):
    """``(group, G)``: the supervariable of each row of the symmetric sparse ``A``
    (:func:`supervariables`) and the quotient graph ``G`` of the groups (CSR, sorted
    indices, no diagonal): an edge ``g - h`` where ``A`` couples a row of ``g`` with
    one of ``h``."""
    A = sp.csr_matrix(A)
    A.sort_indices()
    group = supervariables(A)
    n_groups = int(group[-1]) + 1 if len(group) else 0
    P = sp.csr_matrix((np.ones(len(group)), (np.arange(len(group)), group)),
                      shape=(len(group), n_groups))
    pattern = sp.csr_matrix((np.ones(A.nnz), A.indices, A.indptr), shape=A.shape)
    pattern = pattern + pattern.T     # values symmetric, pattern maybe not: stored zeros
    G = (P.T @ pattern @ P).tocsr()
    G.setdiag(0)
    G.eliminate_zeros()
    G.sort_indices()
    return group, G


def supervariables(A) -> np.ndarray:
    """Group number of each row of the CSR matrix ``A`` (sorted indices): consecutive
    rows with the same column pattern share a group, numbered 0, 1, ... in row order.
    Exact (patterns compared entry by entry, no hashing)."""
    n = A.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    ptr = A.indptr
    length = np.diff(ptr)
    same = length[1:] == length[:-1]                 # row i + 1 against row i
    rows = np.flatnonzero(same & (length[:-1] > 0))   # empty rows: same pattern
    if len(rows):
        sizes = length[rows]
        first = np.cumsum(sizes) - sizes                  # row's first entry in offset
        offset = np.arange(int(sizes.sum())) + np.repeat(ptr[rows] - first, sizes)
        differs = A.indices[offset] != A.indices[offset + np.repeat(sizes, sizes)]
        same[rows[np.add.reduceat(differs, first) > 0]] = False
    return np.concatenate([[0], np.cumsum(~same)]).astype(np.int64)


@register_backend("metis_superlu", requires="pymetis")
def _schur_metis_superlu(K, C, E) -> SchurParts:
    r"""One SuperLU factorisation gives both ``Kc`` and the solver.

    With ``p`` the METIS ordering of ``K_EE`` (``A = K_EE[p][:, p]``, ``B = K_CE[:, p]``),
    SuperLU factorises, in that order and without pivoting, the block upper triangular

    .. math:: M = \begin{bmatrix} A & B^T \\ 0 & I \end{bmatrix}
              = \begin{bmatrix} L & 0 \\ 0 & I \end{bmatrix}
                \begin{bmatrix} D L^T & U_{EC} \\ 0 & I \end{bmatrix},
              \qquad U_{EC} = L^{-1} B^T,

    so the C columns are never updated by each other (no dense |C| x |C|
    factorisation) and ``Kc = K_CC - U_EC^T D^{-1} U_EC``, summed in dense blocks of
    :data:`SCHUR_UPDATE_COLUMNS` rows of ``U_EC`` over the columns they touch. ``U``
    gives both ``D`` (the pivots) and ``U_EC`` (a column slice; the former
    ``[[A, 0], [B, I]]`` needed ``L_CE``, a row slice of L), and SuperLU's L holds no
    interface rows. scipy's copies of L and U are emptied afterwards
    (:func:`_drop_extracted_factors`).
    ``M [x; y] = [b; 0]`` gives ``y = 0`` and ``x = A^-1 b``: the same factor is the
    solver."""
    t0 = time.perf_counter()
    nE, nC = len(E), len(C)
    K_EE = K[E][:, E]
    p = nested_dissection(K_EE)
    A = K_EE[p][:, p]
    M = sp.bmat([[A, K[E[p]][:, C]], [None, sp.identity(nC)]], format="csc")
    a = A.diagonal()
    del K_EE, A                      # not held next to the factor and scipy's copies
    t1 = time.perf_counter()
    try:
        with one_blas_thread():      # small supernode blocks: see solved_by_columns
            lu = spla.splu(M, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
    except RuntimeError:             # "Factor is exactly singular"
        return SchurParts(np.zeros((nC, nC)), None, -np.inf, {})
    identity = np.arange(nE + nC)
    if not (np.array_equal(lu.perm_r, identity) and np.array_equal(lu.perm_c, identity)):
        return _schur_superlu_partial(K, C, E)   # SuperLU reordered or pivoted
    del M
    U = lu.U.tocsc()
    d = U.diagonal()[:nE]
    ratio = float(np.min(d / a))
    t2 = time.perf_counter()
    if not ratio > PIVOT_RATIO_MIN:
        return SchurParts(np.zeros((nC, nC)), None, ratio, {})
    L_CE = _coupling_transposed(U, nE)             # U_EC^T, CSR: one copy of U_EC
    del U
    _drop_extracted_factors(lu)
    Kc = _low_rank_sum(L_CE, 1.0 / d)             # its CSC conversion, copies gone
    del L_CE
    Kc *= -1.0
    K_CC = K[C][:, C].tocoo()                     # added entry by entry: no dense copy
    Kc[K_CC.row, K_CC.col] += K_CC.data           # (canonical: no repeated entries)
    t3 = time.perf_counter()
    return SchurParts(Kc, _bordered_solver(lu, p, nC), ratio,
                      {"ordering": t1 - t0, "factorization": t2 - t1, "schur": t3 - t2})


def _coupling_transposed(U, nE):
    r"""``U_EC^T`` (CSR, |C| x |E|) from the CSC ``U`` of the bordered factorisation of
    :func:`_schur_metis_superlu`, read from the arrays of U's last |C| columns.

    Those columns hold ``U_EC`` and the unit diagonal of ``U_CC = I`` (nothing updates
    the trailing identity block): one entry of row ``>= nE`` per column, in its own
    column, which is dropped; the CSC arrays of ``U_EC`` that remain are the CSR arrays
    of its transpose. One copy of ``U_EC`` (data and row indices) is made, where
    slicing ``U[:nE, nE:]`` and converting it made three while scipy's copies of both
    triangles were held (the peak of the condensation). Falls back to that slicing if
    the trailing block is not the identity pattern."""
    nC = U.shape[1] - nE
    start = U.indptr[nE]
    rows = U.indices[start:]
    keep = rows < nE
    dropped = np.flatnonzero(~keep)
    colptr = U.indptr[nE:] - start
    own = np.searchsorted(colptr, dropped, side="right") - 1
    if len(dropped) != nC or not (np.array_equal(own, np.arange(nC))
                                  and np.array_equal(rows[dropped], nE + own)):
        return U[:nE, nE:].tocsr().T.tocsr()
    indptr = colptr - np.arange(nC + 1, dtype=colptr.dtype)
    return sp.csr_matrix((U.data[start:][keep], rows[keep], indptr), shape=(nC, nE))


def _low_rank_sum(L_CE, d):
    r"""``L_CE diag(d) L_CE^T`` (dense, d > 0; ``L_CE`` sparse, CSC) in blocks of columns, each block a
    symmetric rank-k update (BLAS ``dsyrk``, upper triangle) over the rows it touches
    (found by a mask, not a sort):
    the nested-dissection order keeps the early blocks (subdomains) on few rows, only
    the last (separators) touch all of C. The lower triangle is mirrored at the end."""
    L_CE = sp.csc_matrix(L_CE)
    nC, nE = L_CE.shape
    ptr, rows_of = L_CE.indptr, L_CE.indices
    root = np.sqrt(d)
    out = np.zeros((nC, nC), order="F")
    touched = np.zeros(nC, dtype=bool)
    local_of = np.zeros(nC, dtype=np.int64)
    for j in range(0, nE, SCHUR_UPDATE_COLUMNS):
        k = min(j + SCHUR_UPDATE_COLUMNS, nE)
        a, b = ptr[j], ptr[k]
        if a == b:
            continue
        touched[:] = False
        touched[rows_of[a:b]] = True
        rows = np.flatnonzero(touched)              # sorted: upper stays upper
        local_of[rows] = np.arange(len(rows))
        cols = np.repeat(np.arange(k - j), np.diff(ptr[j:k + 1]))
        D = np.zeros((len(rows), k - j), order="F")
        D[local_of[rows_of[a:b]], cols] = L_CE.data[a:b] * root[j + cols]
        if len(rows) == nC:
            sla_blas.dsyrk(1.0, D, beta=1.0, c=out, overwrite_c=True, lower=0)
        else:
            out[np.ix_(rows, rows)] += sla_blas.dsyrk(1.0, D, lower=0)
    return mirror_triangle(out.T, "lower")          # C order, no copy


def _bordered_solver(lu, p, nC):
    """``K_EE^-1 b`` from the LU of ``[[A, 0], [B, I]]``, ``A = K_EE[p][:, p]``."""
    nE = len(p)

    def whole(b):
        rhs = np.zeros((nE + nC,) + b.shape[1:], order="F")
        rhs[:nE] = b[p]
        x = np.empty_like(b)
        x[p] = lu.solve(rhs)[:nE]
        return x

    def solve(b):
        return solved_by_columns(whole, b)
    return solve


# ----------------------------------------------------------------------------------
# Multifrontal Cholesky on a METIS separator tree (numpy/scipy + pymetis)

@register_backend("multifrontal", requires="pymetis")
def _schur_multifrontal(K, C, E) -> SchurParts:
    r"""Dense-front Cholesky ``K_EE = L L^T`` on a nested-dissection tree of the node
    graph (:mod:`qsma.multifrontal`); the interface rows are carried in every front
    and never eliminated, so their updates sum to ``K_CE K_EE^{-1} K_EC``. The factor
    (one triangle) is the solver, called on all the columns at once with one BLAS
    thread: its loop over the fronts holds the GIL between the BLAS calls, so the
    column blocks of :func:`solved_by_columns` on two threads wait for each other
    (12 columns, quiet machine: 40 ms in one call against 98 ms on two threads for
    the 3d-1 block, 352 against 784 ms for 3d-2;
    ``python benchmarks/bench_schur.py --solve-split --cases 3d-1 3d-2``), and one
    BLAS thread keeps the bits of a solve independent of the machine's thread count."""
    from . import multifrontal
    Kc, factor, ratio, timings = multifrontal.schur_parts(K, C, E)
    if factor is None or not ratio > PIVOT_RATIO_MIN:
        return SchurParts(Kc, None, ratio, timings)

    def solve(b):
        with one_blas_thread():
            return factor.solve(b)
    return SchurParts(Kc, solve, ratio, timings)


# ----------------------------------------------------------------------------------
# CHOLMOD through cvxopt

@register_backend("cholmod", requires="cvxopt")
def _schur_cholmod(K, C, E) -> SchurParts:
    r"""Supernodal Cholesky ``P K P^T = L L^T`` (CHOLMOD, cvxopt's wheel) with
    ``P = [E (AMD of K_EE), C]`` and no postorder, so that ``Kc = L_CC L_CC^T``.
    Reading ``L`` turns cvxopt's factor into a symbolic one, so the solver is a second
    CHOLMOD factor, of ``K_EE`` with CHOLMOD's own ordering (cheap: no dense C block)."""
    import cvxopt
    from cvxopt import amd, cholmod

    t0 = time.perf_counter()
    nE, n = len(E), K.shape[0]
    K_EE = K[E][:, E]
    A_EE = _cvx_lower(K_EE, cvxopt)
    pE = np.asarray(amd.order(A_EE), dtype=np.int64).ravel()
    order = np.concatenate([E[pE], C])
    A = _cvx_lower(K[order][:, order], cvxopt)
    L = _cholmod_factor(A, cvxopt, cholmod, p=cvxopt.matrix(np.arange(n).tolist()),
                        supernodal=2, postorder=False, nmethods=1)
    if L is None:
        return SchurParts(np.zeros((len(C), len(C))), None, -np.inf, {})
    colptr, rows, vals = (np.asarray(a).ravel() for a in cholmod.getfactor(L).CCS)
    diag = vals[colptr[:-1]]                      # sorted columns: diagonal first
    ratio = float(np.min(diag[:nE] ** 2 / K_EE.diagonal()[pE]))
    s = colptr[nE]
    L_CC = sp.csc_matrix((vals[s:], rows[s:] - nE, colptr[nE:] - s),
                         shape=(len(C), len(C))).toarray()
    Kc = L_CC @ L_CC.T
    t1 = time.perf_counter()
    F = _cholmod_factor(A_EE, cvxopt, cholmod)
    t2 = time.perf_counter()
    return SchurParts(Kc, _cholmod_solver(F, cvxopt, cholmod), ratio if F else -np.inf,
                      {"schur": t1 - t0, "factorization": t2 - t1})


def _cvx_lower(A, cvxopt):
    A = sp.tril(A, format="coo")
    return cvxopt.spmatrix(A.data, A.row.astype(np.int64), A.col.astype(np.int64), A.shape)


def _cholmod_factor(A, cvxopt, cholmod, p=None, **options):
    """Numeric CHOLMOD factor of ``A`` (None if not positive definite); ``options``
    temporarily override ``cvxopt.cholmod.options``."""
    saved = dict(cholmod.options)
    cholmod.options.update(options)
    try:
        F = cholmod.symbolic(A) if p is None else cholmod.symbolic(A, p=p)
        cholmod.numeric(A, F)
        return F
    except ArithmeticError:
        return None
    finally:
        cholmod.options.clear()
        cholmod.options.update(saved)


def _cholmod_solver(F, cvxopt, cholmod):
    def solve(b):
        X = cvxopt.matrix(np.asfortranarray(b.reshape(b.shape[0], -1)))
        cholmod.solve(F, X)
        return np.array(X).reshape(b.shape)
    return solve


# ----------------------------------------------------------------------------------
# MKL PARDISO (through pypardiso's mkl_rt)

_PARDISO_ERRORS = {-1: "input inconsistent", -2: "not enough memory",
                   -3: "reordering problem", -4: "zero pivot (matrix not positive definite)",
                   -5: "unclassified internal error", -6: "reordering failed",
                   -7: "diagonal matrix is singular", -8: "32-bit integer overflow",
                   -9: "not enough memory for out-of-core", -10: "error opening OOC files",
                   -11: "read/write error with OOC files"}


class _Pardiso:
    """One PARDISO handle for a real SPD matrix (``mtype = 2``, upper triangle, 0-based
    indices), released when the object is collected."""

    def __init__(self, A, *, schur_rows=None, keep_diagonal=False):
        self.lib = _mkl_rt()
        self.n = A.shape[0]
        U = sp.triu(A, format="csr")
        U.sort_indices()
        self.a = np.ascontiguousarray(U.data, dtype=float)
        self.ia = U.indptr.astype(np.int32)
        self.ja = U.indices.astype(np.int32)
        self.pt = np.zeros(64, dtype=np.int64)
        self.iparm = np.zeros(64, dtype=np.int32)
        self.iparm[[0, 1, 34]] = (1, 2, 1)        # own iparm, METIS ordering, 0-based
        self.perm = np.zeros(self.n, dtype=np.int32)
        if schur_rows is not None:
            self.iparm[35] = 1                    # Schur complement during factorisation
            self.perm[schur_rows] = 1
        if keep_diagonal:
            self.iparm[55] = 1                    # pivots for pardiso_getdiag
        self._finalizer = weakref.finalize(self, _pardiso_release, self.lib, self.pt,
                                           self.n, self.a, self.ia, self.ja, self.perm,
                                           self.iparm)

    def call(self, phase, b, x, nrhs=1):
        err = _pardiso_call(self.lib, self.pt, phase, self.n, self.a, self.ia, self.ja,
                            self.perm, nrhs, self.iparm, b, x)
        if err == -4 or err == -7:
            raise InputError(f"K_EE is singular or not positive definite (PARDISO error "
                             f"{err}: {_PARDISO_ERRORS[err]}); the body is not held "
                             f"against rigid-body motion apart from its interface: add "
                             f"clamps")
        if err != 0:
            raise AnalysisError(f"PARDISO phase {phase} failed with error {err}: "
                                f"{_PARDISO_ERRORS.get(err, 'unknown')}")

    def pivot_ratio(self):
        """``min_i d_i / a_ii`` from ``pardiso_getdiag`` (``d_i = l_ii^2`` for LL^T)."""
        df, da = np.zeros(self.n), np.zeros(self.n)
        err = ctypes.c_int32(0)
        getdiag = self.lib["pardiso_getdiag"]
        getdiag.restype = None
        getdiag(self.pt.ctypes.data_as(ctypes.c_void_p), df.ctypes.data_as(ctypes.c_void_p),
                da.ctypes.data_as(ctypes.c_void_p), ctypes.byref(ctypes.c_int32(1)),
                ctypes.byref(err))
        if err.value != 0:
            raise AnalysisError(f"pardiso_getdiag failed with error {err.value}")
        return float(np.min(df / da))


def _pardiso_call(lib, pt, phase, n, a, ia, ja, perm, nrhs, iparm, b, x):
    fn = lib["pardiso"]
    fn.restype = None
    i32, ptr = ctypes.c_int32, (lambda arr: arr.ctypes.data_as(ctypes.c_void_p))
    err = i32(0)
    fn(ptr(pt), ctypes.byref(i32(1)), ctypes.byref(i32(1)), ctypes.byref(i32(2)),
       ctypes.byref(i32(phase)), ctypes.byref(i32(n)), ptr(a), ptr(ia), ptr(ja), ptr(perm),
       ctypes.byref(i32(nrhs)), ptr(iparm), ctypes.byref(i32(0)), ptr(b), ptr(x),
       ctypes.byref(err))
    return err.value


def _pardiso_release(lib, pt, n, a, ia, ja, perm, iparm):
    dummy = np.zeros(1)
    _pardiso_call(lib, pt, -1, n, a, ia, ja, perm, 1, iparm, dummy, dummy)


_MKL_RT = []


def _mkl_rt():
    """``mkl_rt`` as found by pypardiso (its env variable, library path or wheel)."""
    if not _MKL_RT:
        import pypardiso
        _MKL_RT.append(pypardiso.PyPardisoSolver().libmkl)
    return _MKL_RT[0]


@register_backend("pardiso", requires="pypardiso")
def _schur_pardiso(K, C, E) -> SchurParts:
    r"""PARDISO (MKL) factorises ``K`` with the C rows marked as Schur rows
    (``iparm(36) = 1``): it orders E by nested dissection, eliminates it and returns
    the dense ``Kc`` (rows in increasing DOF number). A second PARDISO Cholesky, of
    ``K_EE`` alone, is the solver (its partial solves in Schur mode are less accurate)
    and gives the pivots."""
    t0 = time.perf_counter()
    nC = len(C)
    full = _Pardiso(K, schur_rows=C)
    out = np.zeros(max(nC * nC, K.shape[0]))
    full.call(12, np.zeros_like(out), out)
    del full                                      # release its factor now
    rank = np.argsort(np.argsort(C))              # C[i] is the rank[i]-th Schur row
    Kc = out[:nC * nC].reshape(nC, nC)[np.ix_(rank, rank)]
    t1 = time.perf_counter()
    ee = _Pardiso(K[E][:, E], keep_diagonal=True)
    ee.call(12, np.zeros(len(E)), np.zeros(len(E)))
    ratio = ee.pivot_ratio()
    t2 = time.perf_counter()
    return SchurParts(Kc, _pardiso_solver(ee), ratio,
                      {"schur": t1 - t0, "factorization": t2 - t1})


def _pardiso_solver(ee):
    def solve(b):
        B = np.asfortranarray(b.reshape(ee.n, -1))
        X = np.zeros_like(B)
        ee.call(33, B, X, nrhs=B.shape[1])
        return X.reshape(b.shape)
    return solve


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
