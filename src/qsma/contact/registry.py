"""Registry of contact methods and the one entry point :func:`solve`."""
from __future__ import annotations

import inspect
import warnings
from typing import NamedTuple

import numpy as np

from ..errors import ContactConvergenceWarning, InputError
from .law import classify, pair_quantities
from .residual import force_scale, residual
from .state import ContactResult, ContactState

#: name -> solver function; filled by :func:`register_method`.
METHODS = {}
#: name -> the method's own keyword options.
_OPTIONS = {}

#: Default relative tolerance of :func:`solve` on :func:`residual`. The exact
#: block solves reach ~1e-15 (round-off of ``K d`` relative to the force
#: scale, measured up to cond(K) = 1e6 in benchmarks/bench_contact.py); 1e-10
#: keeps a margin of >1e3 above that floor.
DEFAULT_TOL = 1e-10


class Iterate(NamedTuple):
    """What a method hands back to :func:`solve`.

    ``d``, ``lam`` (n_pairs, dim) the last iterate, ``nit`` iterations,
    ``converged`` whether the method's own stopping test (the residual)
    passed, ``message`` a sentence for the user.
    """

    d: np.ndarray
    lam: np.ndarray
    nit: int
    converged: bool
    message: str


def register_method(name):
    """Decorator registering a solver function under ``name`` in :data:`METHODS`.

    The function is called as ``fn(problem, lam_w, previous, *, tol, maxiter,
    **options)`` with ``lam_w`` ``(n_pairs, dim)``, ``previous`` a
    :class:`ContactState`, ``maxiter`` ``None`` for the method's default, and
    returns an :class:`Iterate`. Its other keyword-only parameters are its
    options.
    """
    def register(fn):
        if name in METHODS:
            raise ValueError(f"contact method {name!r} registered twice")
        METHODS[name] = fn
        _OPTIONS[name] = tuple(p.name for p in inspect.signature(fn).parameters.values()
                               if p.kind is p.KEYWORD_ONLY and p.name not in ("tol", "maxiter"))
        return fn
    return register


def solve(problem, lam_w, state=None, *, method="basket", tol=DEFAULT_TOL, maxiter=None,
          **options):
    """Solve one load level of the frictional contact problem.

    Find ``d`` and ``lam = K d + lam_w`` such that every pair is open, stuck
    or slipping (method.md section 4), the slip increment measured from
    ``state``.

    Parameters
    ----------
    problem : ContactProblem
    lam_w : (n_pairs, dim) array_like
        Welded contact force of this load level.
    state : ContactState, optional
        Previous converged state (warm start and slip reference). ``None``:
        the undeformed reference (``d = 0``), every pair guessed stuck.
    method : str
        A key of :data:`METHODS`: ``"basket"`` (default), ``"active_set"``,
        ``"nodal_gs"``.
    tol : float
        Success means ``residual(...) <= tol`` (relative, see :func:`residual`).
    maxiter : int, optional
        Cap on ``nit``, the iterations of the method including any fallback
        (``None``: the method's own defaults, see docs/contact.md).
    **options
        Keyword options of the method; an unknown name raises.

    Returns
    -------
    ContactResult
        ``success=False`` (with a :class:`ContactConvergenceWarning`) if the
        tolerance was not met; ``d``, ``lam``, ``state`` then hold the last
        iterate.

    Raises
    ------
    InputError
        Unknown method or option, bad ``tol``/``maxiter``, ``lam_w`` of the
        wrong shape or not finite, a state of another problem.
    """
    fn = _lookup(method, options)
    lam_w = _check_load(problem, lam_w)
    previous = ContactState.reference(problem) if state is None else state.check_against(problem)
    out = fn(problem, lam_w, previous, tol=_check_tol(tol), maxiter=_check_maxiter(maxiter),
             **options)
    return _result(problem, lam_w, previous, out, method, tol)


def _lookup(method, options):
    if method not in METHODS:
        raise InputError(f"unknown contact method {method!r}; valid: {sorted(METHODS)}")
    unknown = sorted(set(options) - set(_OPTIONS[method]))
    if unknown:
        raise InputError(f"unknown option(s) {unknown} for contact method {method!r}; "
                         f"valid: {['tol', 'maxiter', *_OPTIONS[method]]}")
    return METHODS[method]


def _check_load(problem, lam_w):
    lam_w = np.array(lam_w, dtype=float)
    shape = (problem.n_pairs, problem.dim)
    if lam_w.shape != shape:
        raise InputError(f"lam_w must have shape {shape} (n_pairs, dim), got {lam_w.shape}")
    if not np.all(np.isfinite(lam_w)):
        raise InputError(f"lam_w must be finite: found {np.count_nonzero(~np.isfinite(lam_w))} "
                         "NaN/Inf values")
    return lam_w


def _check_tol(tol):
    if not (np.isscalar(tol) and np.isfinite(tol) and tol > 0):
        raise InputError(f"tol must be a positive finite number, got {tol!r}")
    return float(tol)


def _check_maxiter(maxiter):
    if maxiter is None:
        return None
    if isinstance(maxiter, bool) or not isinstance(maxiter, (int, np.integer)) or maxiter < 1:
        raise InputError(f"maxiter must be a positive integer or None, got {maxiter!r}")
    return int(maxiter)


def _result(problem, lam_w, previous, out, method, tol):
    """Accept or reject the method's iterate on the public residual, warn on failure."""
    r = residual(problem, lam_w, out.d, out.lam, previous)
    success = bool(out.converged and r <= tol)
    message = out.message
    if out.converged and not success:
        message = f"{message}; rejected: residual {r:.3e} > tol {tol:.1e}"
    q = pair_quantities(problem, out.d, out.lam, previous.d)
    status = classify(q, problem.mu, problem.kappa, tol * force_scale(lam_w, out.lam))
    state = ContactState(out.d, out.lam, status)
    if not success:
        warnings.warn(f"contact method {method!r}: {message} (residual {r:.3e}, tol {tol:.1e})",
                      ContactConvergenceWarning, stacklevel=3)
    return ContactResult(state.d, state.lam, state.status, success, out.nit, float(r), message,
                         method, state)
