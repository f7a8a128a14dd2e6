"""The reduced frictional contact problem ``lam = K d + lam_w`` (method.md section 3)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import blas as sla_blas

from .._infra.dense import symmetrised
from ..errors import InputError

#: Relative asymmetry accepted in K: ``max|K - K^T| <= SYMMETRY_RTOL * max|K|``.
#: A condensed K = Kc1 (Kc1 + Kc2)^-1 Kc2 carries round-off asymmetry of about
#: cond(K) * eps ~ 2e6 * 2.2e-16 ~ 5e-10 (FIELD-NOTES, sandwich-2d); 1e-8 leaves
#: a factor 20 above that and still rejects a genuinely asymmetric matrix.
SYMMETRY_RTOL = 1e-8
#: Unknowns from which :meth:`ContactProblem.abs_product` works in single precision:
#: below, ``|K|`` in double fits the cache (1000 unknowns: 8 MB); sandwich-3d refine 1
#: (1683 unknowns) checks each level with one double and one single product instead of
#: two double ones, refine 2 (6435) keeps 165 MB instead of 330 MB for it.
SINGLE_PRECISION_FROM = 1000


@dataclass(frozen=True, eq=False, repr=False)
class ContactProblem:
    """Frictional contact of two bodies reduced to the interface node pairs.

    The contact force on body 2 is affine in the relative displacement,

    .. math:: \\lambda = K d + \\lambda_w ,

    with one block of ``dim`` components per node pair in the local frame of
    the pair, ordered ``(t, n)`` in 2D and ``(t1, t2, n)`` in 3D (pair-major).

    Parameters
    ----------
    K : (n_pairs*dim, n_pairs*dim) array_like
        Interface stiffness, symmetric positive definite. Stored symmetrised,
        ``(K + K^T) / 2``.
    mu : float or (n_pairs,) array_like
        Coulomb friction coefficient, ``>= 0``; stored per pair.
    gap0 : (n_pairs,) array_like, optional
        Initial normal gap ``g0`` (opening ``w = d_n + g0``); default 0.
    dim : {2, 3}
        Spatial dimension of the pair frames.

    Raises
    ------
    InputError
        With the expected and the actual value, for a K that is not square,
        not a multiple of ``dim``, not finite, not symmetric or not positive
        definite, and for a bad ``mu``, ``gap0`` or ``dim``.

    Attributes
    ----------
    n_pairs : int
    kappa : float
        Stiffness scale, the mean of ``diag(K)``; used by the residual.
    normal_index : (n_pairs,) int
        Flat index of the normal component of each pair.
    tangent_index : (n_pairs, dim-1) int
        Flat indices of the tangential components.
    diagonal_blocks : (n_pairs, dim, dim)
        ``K_ii``, the stiffness of each pair alone.
    """

    K: np.ndarray
    mu: np.ndarray
    gap0: np.ndarray | None = None
    dim: int = 2
    n_pairs: int = field(init=False)
    kappa: float = field(init=False)
    normal_index: np.ndarray = field(init=False)
    tangent_index: np.ndarray = field(init=False)
    diagonal_blocks: np.ndarray = field(init=False)

    def __post_init__(self):
        dim = _check_dim(self.dim)
        K = _check_stiffness(self.K, dim)
        n = K.shape[0] // dim
        _set_fields(self, K=K, dim=dim,
                    mu=_check_per_pair("mu", self.mu, n, default=None, nonnegative=True),
                    gap0=_check_per_pair("gap0", self.gap0, n, default=0.0,
                                         nonnegative=False),
                    **_derived_fields(K, dim))

    @classmethod
    def derived(cls, K, mu, gap0, dim, *, overwrite=False):
        """A problem the package derived from a validated one (the Schur complement of
        an SPD ``K`` on a zone, with that zone's ``mu`` and ``gap0``): ``K`` is
        symmetrised and nothing else is checked again (the Cholesky test alone costs
        ``n^3/3``).

        ``overwrite=True``: ``K`` is the caller's own float64 array, symmetrised in place
        (:func:`qsma._infra.dense.symmetrised`, the same bits as ``(K + K^T) / 2``), frozen
        and held: no copy of the zone's size."""
        K = _frozen(symmetrised(K) if overwrite else 0.5 * (K + K.T))
        new = object.__new__(cls)
        _set_fields(new, K=K, mu=_frozen(np.array(mu, dtype=float)),
                    gap0=_frozen(np.array(gap0, dtype=float)), dim=int(dim),
                    **_derived_fields(K, int(dim)))
        return new

    def product(self, x):
        r"""``K x`` for a vector ``x`` (N,), reading one triangle of the symmetric ``K``.

        ``K`` is stored exactly symmetric, so the symmetric matrix-vector product of
        BLAS (``dsymv``) gives ``K x`` up to round-off while reading half the matrix:
        the checks of a solve are limited by memory traffic (measured 0.6 ms against
        1.35 ms for ``K @ x`` at N = 1683, 16 against 33 ms at N = 6435). Used by the
        measures (:mod:`qsma.contact.residual`), the basket and the iterates of
        ``active_set``; ``nodal_gs`` iterates with ``K @ x``.
        """
        return _symmetric_product(self.K, np.asarray(x, dtype=float).ravel())

    def abs_product(self, x, symmetric=False):
        r"""``|K| |x|``, the size of the terms of ``K x`` (the residual's scale).

        From :data:`SINGLE_PRECISION_FROM` unknowns on it is evaluated in single
        precision on ``|K|`` and ``|x|`` scaled by powers of two (no overflow or
        underflow of what matters): half the memory traffic and storage of a second
        dense product. All terms are positive, so the relative error is at most
        ``N 2^-24`` (``~ sqrt(N) 2^-24`` in practice), which a scale tolerates.
        ``symmetric=True``: one triangle read (BLAS ``symv``, see :meth:`product`),
        what the measures and the basket use; the default is the plain product.
        """
        ax = np.abs(np.asarray(x, dtype=float).ravel())
        times = _symmetric_product if symmetric else np.matmul
        if self.size < SINGLE_PRECISION_FROM:
            return times(self.abs_K, ax)
        top = ax.max(initial=0.0)
        if not np.isfinite(top):
            return np.abs(self.K) @ ax                # NaN/Inf as the exact product has them
        if top == 0.0:
            return np.zeros_like(ax)
        A, scale = self._abs_single()
        s = _power_of_two(top)
        with np.errstate(under="ignore"):
            y = times(A, (ax / s).astype(np.float32))
        return y.astype(float) * (scale * s)

    def _abs_single(self):
        """``(|K| / scale in float32, scale)``, scale a power of two near ``max|K|``."""
        cached = self.__dict__.get("_abs_single_K")
        if cached is None:
            scale = _power_of_two(np.abs(self.K).max())
            with np.errstate(under="ignore"):
                cached = (_frozen((np.abs(self.K) / scale).astype(np.float32)), scale)
            self.__dict__["_abs_single_K"] = cached
        return cached

    def cached(self, name, make):
        """``make(self)``, computed once for this problem and kept (per-pair stiffness,
        row sums of ``|K|``: what every check of a solve reads). A rescaled copy
        (:meth:`rescaled`) keeps its own values, shared by every copy of the same
        stiffness."""
        cache = self.__dict__.setdefault("_derived", {})
        value = cache.get(name)
        if value is None:
            value = cache[name] = _frozen(make(self))
        return value

    @property
    def abs_row_sums(self):
        """``sum_k |K_jk|`` of every row (N,): a bound of ``|K| |x|`` by ``max|x|``."""
        return self.cached("abs_row_sums", lambda p: np.abs(p.K).sum(axis=1))

    @property
    def abs_K(self):
        """``|K|`` (element-wise), built once on first use: the residual's round-off
        allowance multiplies it by ``|d|`` at every check of a solve."""
        cached = self.__dict__.get("_abs_K")
        if cached is None:
            cached = _frozen(np.abs(self.K))
            self.__dict__["_abs_K"] = cached
        return cached

    def rescaled(self, stiffness, length):
        """The same problem in other units: ``K / stiffness``, ``gap0 / length``.

        Forces then count in ``stiffness * length``. No validation is repeated
        (a positive rescaling keeps every property); the last rescaled copy is
        cached, and ``self`` is returned for ``(1, 1)``.
        """
        if stiffness == 1.0 and length == 1.0:
            return self
        cache = self.__dict__.setdefault("_rescaled", {})
        if cache.get("stiffness") != stiffness:
            cache.clear()
            cache["stiffness"] = stiffness
            cache["K"] = _frozen(self.K / stiffness)
            cache["blocks"] = _frozen(self.diagonal_blocks / stiffness)
        new = object.__new__(ContactProblem)
        _set_fields(new, K=cache["K"], mu=self.mu, gap0=_frozen(self.gap0 / length),
                    dim=self.dim, n_pairs=self.n_pairs, kappa=self.kappa / stiffness,
                    normal_index=self.normal_index, tangent_index=self.tangent_index,
                    diagonal_blocks=cache["blocks"])
        new.__dict__["_derived"] = cache.setdefault("derived", {})
        if self.size >= SINGLE_PRECISION_FROM:
            A, scale = self._abs_single()               # |K / stiffness|, same bits
            new.__dict__["_abs_single_K"] = (A, scale / stiffness)
            return new
        if "abs_K" not in cache:
            cache["abs_K"] = _frozen(np.abs(cache["K"]))
        new.__dict__["_abs_K"] = cache["abs_K"]       # shared by every solve of the ramp
        return new

    def __getstate__(self):
        """Pickled without what is cached on the problem (``|K|``, rescaled copies, the
        last contact-zone elimination: each as large as ``K``), rebuilt where needed:
        a problem shipped to another process (the loops on a Dask scheduler) weighs
        its fields only."""
        return {k: v for k, v in self.__dict__.items() if not k.startswith("_")}

    @property
    def size(self):
        """Number of unknowns, ``n_pairs * dim``."""
        return self.n_pairs * self.dim

    def __repr__(self):
        mu = np.unique(self.mu)
        mu_text = f"{mu[0]:g}" if mu.size == 1 else f"[{mu.min():g}..{mu.max():g}]"
        return (f"ContactProblem(n_pairs={self.n_pairs}, dim={self.dim}, mu={mu_text}, "
                f"kappa={self.kappa:.4g}, max_gap0={np.max(np.abs(self.gap0)):.3g})")


def _symmetric_product(A, x):
    """``A x`` for an exactly symmetric C-ordered ``A`` (float64 or float32) and a vector
    ``x`` of its type: BLAS ``symv`` on ``A.T``, the same matrix in Fortran order (no
    copy), reading one triangle."""
    symv = sla_blas.ssymv if A.dtype == np.float32 else sla_blas.dsymv
    return symv(1.0, A.T, x)


def _power_of_two(x):
    """``2**round(log2 x)`` for finite ``x > 0``, 1 otherwise."""
    if not (np.isfinite(x) and x > 0):
        return 1.0
    return float(2.0 ** round(np.log2(x)))


def _frozen(array):
    array.flags.writeable = False
    return array


def _check_dim(dim):
    if dim not in (2, 3) or isinstance(dim, bool):
        raise InputError(f"dim must be 2 or 3, got {dim!r}")
    return int(dim)


def _check_stiffness(K, dim):
    shared = _shareable(K)
    K = K if shared else np.array(K, dtype=float)
    if K.ndim != 2 or K.shape[0] != K.shape[1]:
        raise InputError(f"K must be a square matrix: expected shape (N, N), got {K.shape}")
    if K.shape[0] == 0 or K.shape[0] % dim:
        raise InputError(f"K must have a positive multiple of dim={dim} rows "
                         f"(one block of {dim} per pair): got {K.shape[0]}")
    bad = np.count_nonzero(~np.isfinite(K))
    if bad:
        raise InputError(f"K must be finite: found {bad} NaN/Inf entries")
    if not (shared and np.array_equal(K, K.T)):
        _check_symmetric(K)
        K, shared = 0.5 * (K + K.T), False
    try:
        np.linalg.cholesky(K)
    except np.linalg.LinAlgError:
        raise InputError("K must be positive definite: its Cholesky factorisation failed "
                         f"(smallest diagonal entry {np.min(np.diag(K)):.3e})") from None
    return K if shared else _frozen(K)


def _shareable(K):
    """Whether the problem may hold ``K`` itself rather than a copy: a read-only,
    C-ordered, square float64 array (nothing writes to it through the problem, and its
    owner has frozen it; the reduced model of an analysis does, which saves a dense copy
    of the interface size, 331 MB at 6,435 unknowns). It is used as is only if it is also
    exactly symmetric, when symmetrising would return the same bits."""
    return (isinstance(K, np.ndarray) and K.dtype == np.float64 and K.ndim == 2
            and K.shape[0] == K.shape[1] and K.flags.c_contiguous and _read_only_memory(K))


def _read_only_memory(a):
    """Whether no array in the chain of ``a``'s bases is writeable, and the memory
    belongs to numpy arrays (not a memory map or a foreign buffer): a read-only view of
    a writeable array could still be changed through the array."""
    while a is not None:
        if not isinstance(a, np.ndarray) or isinstance(a, np.memmap) or a.flags.writeable:
            return False
        a = a.base
    return True


def _check_symmetric(K):
    scale = np.max(np.abs(K))
    asym = np.max(np.abs(K - K.T))
    if asym > SYMMETRY_RTOL * scale:
        i, j = np.unravel_index(np.argmax(np.abs(K - K.T)), K.shape)
        raise InputError(
            f"K must be symmetric: expected max|K - K^T| <= {SYMMETRY_RTOL:g} * max|K| = "
            f"{SYMMETRY_RTOL * scale:.3e}, got {asym:.3e} (K[{i},{j}] = {K[i, j]:.6g}, "
            f"K[{j},{i}] = {K[j, i]:.6g})")


def _check_per_pair(name, value, n, default, nonnegative):
    if value is None:
        if default is None:
            raise InputError(f"{name} is required")
        value = default
    array = np.array(value, dtype=float)
    if array.ndim == 0:
        array = np.full(n, float(array))
    if array.shape != (n,):
        raise InputError(f"{name} must be a scalar or have one value per pair: "
                         f"expected shape ({n},), got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InputError(f"{name} must be finite: found {np.count_nonzero(~np.isfinite(array))} "
                         "NaN/Inf values")
    if nonnegative and np.any(array < 0):
        k = int(np.argmin(array))
        raise InputError(f"{name} must be >= 0: got {array[k]:g} at pair {k}")
    return _frozen(array)


def _derived_fields(K, dim) -> dict:
    """The fields of a :class:`ContactProblem` that follow from ``K`` and ``dim``."""
    n = K.shape[0] // dim
    return {"n_pairs": n, "kappa": float(np.mean(np.diag(K))),
            "normal_index": _frozen(np.arange(n) * dim + dim - 1),
            "tangent_index": _frozen(np.arange(n)[:, None] * dim + np.arange(dim - 1)),
            "diagonal_blocks": _frozen(_diagonal_blocks(K, dim))}


def _set_fields(problem, **values):
    """Set the fields of a frozen :class:`ContactProblem`."""
    for name, value in values.items():
        object.__setattr__(problem, name, value)


def _diagonal_blocks(K, dim):
    n = K.shape[0] // dim
    blocks = K.reshape(n, dim, n, dim)
    return blocks[np.arange(n), :, np.arange(n), :].copy()
