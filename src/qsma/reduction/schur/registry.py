"""The registry of Schur backends and :func:`schur_complement`, which validates ``K``
and ``C``, picks a backend (``"auto"``: the first available of :data:`AUTO_ORDER`) and
checks its answer (pivots, finiteness); the backends themselves are one module each in
this package."""
from __future__ import annotations

from dataclasses import dataclass, field
import importlib.util
import time

import numpy as np
import scipy.sparse as sp

from ..._infra.dense import symmetrised
from ...errors import AnalysisError, InputError
from .ordering import supervariables

#: Smallest accepted ``d_i / (K_EE)_ii`` over the pivots ``d_i`` of ``K_EE``. It is
#: ``>= 1 / cond`` of the Jacobi-scaled ``K_EE`` when that is SPD. The sandwich-2d
#: beams and the 3D block of benchmarks/bench_schur.py measure 2e-4 .. 5e-2, depending
#: on the backend's ordering. A rigid-body mode leaves a pivot at round-off level:
#: SuperLU measures -8e-14 .. -4e-14 on the free sandwich beam of
#: tests/test_linalg.py, where CHOLMOD and PARDISO stop at a non-positive pivot.
PIVOT_RATIO_MIN = 1e-12

#: Relative asymmetry ``max|K - K^T| / max|K|`` accepted by :func:`schur_complement`.
SYMMETRY_TOL = 1e-10

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
