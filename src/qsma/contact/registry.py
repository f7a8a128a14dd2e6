"""Registry of contact methods and the one entry point :func:`solve`."""
from __future__ import annotations

import inspect
import warnings
from typing import NamedTuple

import numpy as np

from ..errors import ContactConvergenceWarning, InputError
from .law import classify, natural_map, pair_quantities
from .problem import _power_of_two
from .residual import FORCE_TOL, measures as all_measures, pair_stiffness, reaction_scale
from .state import ContactResult, ContactState, Outcome

#: name -> solver function; filled by :func:`register_method`.
METHODS = {}
#: name -> the method's own keyword options.
_OPTIONS = {}
#: name -> the method that takes over when it fails (``solve(..., fallback=True)``).
#: The one place that decides a hand-over; ``nodal_gs`` is the baseline and has none.
FALLBACKS = {"basket": "active_set", "active_set": "basket"}
#: ``method="auto"`` (the default of a QSMA run, :class:`qsma.RunOptions`) takes
#: ``active_set`` on 3D problems of at least this many pairs and ``basket`` on every
#: other (:func:`chosen_method`). Measured on the 3D joints (docs/contact.md, "Default
#: method"): with the same solves and results to ~1e-11, ``active_set`` took 0.3-0.75
#: of ``basket``'s time in the loops of lap-3d refine 1 and 2 (176 and 651 pairs), the
#: Brake-Reuss beam refine 1 (85) and the Gmsh tetrahedral lap joint (753), and
#: 0.9-1.03 in their ramps; in 2D the two are equal within the noise, and on the
#: adversarial sweep of at most 20 pairs ``basket`` falls back four times less often.
AUTO_ACTIVE_SET_PAIRS = 50
#: Errors a method may raise on extreme but finite input; :func:`solve` turns them
#: into a failed result (``Outcome.NUMERICAL_ERROR``) instead of letting them out.
NUMERICAL_ERRORS = (np.linalg.LinAlgError, ArithmeticError, FloatingPointError, ValueError)

#: Default relative tolerance of :func:`solve` on :func:`residual`. The exact
#: block solves reach ~1e-15 (round-off of ``K d`` relative to the force
#: scale, measured up to cond(K) = 1e6 in benchmarks/bench_contact.py); 1e-10
#: keeps a margin of >1e3 above that floor.
DEFAULT_TOL = 1e-10


class Iterate(NamedTuple):
    """What a method hands back to :func:`solve`.

    ``d``, ``lam`` (n_pairs, dim) the last iterate, ``nit`` iterations,
    ``converged`` whether the method's own stopping test (the residual)
    passed, ``message`` a sentence for the user, ``numerical_error`` set by
    :func:`solve` when the method raised, ``measures`` the
    ``(residual, force_residual, legacy_residual)`` of this very iterate if the
    method evaluated them (:func:`qsma.contact.residual.measures`, on the problem and
    load it was given), so that :func:`solve` does not evaluate them again.
    """

    d: np.ndarray
    lam: np.ndarray
    nit: int
    converged: bool
    message: str
    numerical_error: bool = False
    measures: tuple | None = None


def register_method(name):
    """Decorator registering a solver function under ``name`` in :data:`METHODS`.

    The function is called as ``fn(problem, lam_w, previous, *, tol, maxiter,
    guess, **options)`` with ``lam_w`` ``(n_pairs, dim)``, ``previous`` a
    :class:`ContactState` (the slip reference), ``guess`` a
    :class:`ContactState` to start from (``previous`` unless a fallback hands
    over an iterate), ``maxiter`` ``None`` for the method's default, and
    returns an :class:`Iterate`. Its other keyword-only parameters are its
    options.
    """
    def register(fn):
        if name in METHODS:
            raise ValueError(f"contact method {name!r} registered twice")
        METHODS[name] = fn
        _OPTIONS[name] = tuple(p.name for p in inspect.signature(fn).parameters.values()
                               if p.kind is p.KEYWORD_ONLY
                               and p.name not in ("tol", "maxiter", "guess"))
        return fn
    return register


def chosen_method(method, problem):
    """The method that ``method`` names on ``problem``: ``method`` itself, or for
    ``"auto"`` ``"active_set"`` on a 3D problem of at least
    :data:`AUTO_ACTIVE_SET_PAIRS` pairs and ``"basket"`` otherwise."""
    return method_for(method, problem.dim, problem.n_pairs)


def method_for(method, dim, n_pairs):
    """:func:`chosen_method` for an interface of ``n_pairs`` pairs in ``dim``
    dimensions (before its problem is built)."""
    if method != "auto":
        return method
    return "active_set" if dim == 3 and n_pairs >= AUTO_ACTIVE_SET_PAIRS else "basket"


def method_names():
    """The names a ``method`` argument accepts: ``"auto"`` and the keys of
    :data:`METHODS`."""
    return ["auto", *sorted(METHODS)]


def solve(problem, lam_w, state=None, *, method="basket", tol=DEFAULT_TOL, maxiter=None,
          fallback=True, guess=None, **options):
    """Solve one load level of the frictional contact problem.

    Find ``d`` and ``lam = K d + lam_w`` such that every pair is open, stuck
    or slipping (docs/contact.md), the slip increment measured from
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
        ``"nodal_gs"``; or ``"auto"``, chosen by the problem's size
        (:func:`chosen_method`).
    tol : float
        Success means ``residual(...) <= tol`` (see :func:`residual`) and
        ``force_residual(...) <= FORCE_TOL``.
    maxiter : int, optional
        Cap on ``nit``, the iterations of the method including any fallback
        (``None``: the method's own defaults, see docs/contact.md).
    fallback : bool
        If the method fails, hand over to :data:`FALLBACKS` ``[method]``
        (started from the failed iterate); ``result.fallback`` names it.
    guess : ContactState, optional
        Iterate (and pair states) to start from instead of ``state``, e.g. the
        answer of the same load level on a neighbouring path; the slip is still
        measured from ``state``, and the answer is judged exactly as without it. A
        guess that already meets the check of this level (:func:`guess_measures`) is
        the answer, with ``nit = 0``.
    **options
        Keyword options of the method; an unknown name raises.

    Returns
    -------
    ContactResult
        ``success=False`` (with a :class:`ContactConvergenceWarning`) if the
        tolerance was not met; ``d``, ``lam``, ``state`` then hold the last
        iterate. No exception but :class:`InputError` leaves this function
        for finite input: numerical errors give ``Outcome.NUMERICAL_ERROR``.

    Raises
    ------
    InputError
        Unknown method or option, bad ``tol``/``maxiter``, ``lam_w`` of the
        wrong shape or not finite, a state of another problem.
    """
    if method == "auto" and options:
        raise InputError(f"method options {sorted(options)} belong to one method, and "
                         f"method='auto' chooses by the problem's size: name the method "
                         f"(method='basket' or method='active_set') to pass them")
    method = chosen_method(method, problem)
    fn = _lookup(method, options)
    lam_w = _check_load(problem, lam_w)
    previous = ContactState.reference(problem) if state is None else state.check_against(problem)
    tol, maxiter = _check_tol(tol), _check_maxiter(maxiter)
    scaled = _Scaled(problem, lam_w, previous)
    start = None if guess is None else scaled.to_internal(checked_guess(guess, problem))
    checked = None if start is None else guess_measures(scaled.problem, scaled.lam_w,
                                                        scaled.previous, start, tol)
    if checked is not None:
        return _result(problem, lam_w, previous, accepted_guess(start), method, tol,
                       scaled=scaled, measures=checked)
    out, used, measures = _run_chain(scaled, method, fn, tol, maxiter, bool(fallback),
                                     options, start)
    return _result(problem, lam_w, previous, out, method, tol, fallback=used, scaled=scaled,
                   measures=measures)


def _measures(scaled, out):
    """``(residual, force_residual, legacy_residual)`` of an iterate in the internal
    units of ``scaled`` (one pass over ``K``)."""
    return all_measures(scaled.problem, scaled.lam_w, out.d, out.lam, scaled.previous)


def _run_chain(scaled, method, fn, tol, maxiter, fallback, options, start=None):
    """The method, then its fallback if its answer is not accepted (not converged, or
    rejected by the residual or the force check of :func:`_result`); ``(Iterate,
    fallback name or None, measures of the first iterate or None)``, the iterate in
    the internal units of ``scaled``; ``start`` an iterate to begin from."""
    out = _guarded(fn, scaled, start, tol, maxiter, options)
    rescue = FALLBACKS.get(method)
    left = None if maxiter is None else maxiter - out.nit
    measures = (out.measures or _measures(scaled, out)) if out.converged else None
    accepted = measures is not None and measures[0] <= tol and measures[1] <= FORCE_TOL
    if accepted or not fallback or rescue is None or left == 0:
        return out, None, measures
    guess = None if out.numerical_error else scaled.guess(out)
    second = _guarded(METHODS[rescue], scaled, guess, tol, left, {})
    merged = second._replace(nit=out.nit + second.nit,
                             message=f"{out.message}; fell back to {rescue}: {second.message}")
    return merged, rescue, merged.measures


def guess_measures(problem, lam_w, previous, guess, tol):
    r"""The measures of ``guess`` taken as the answer of this level, if it is one.

    A state of a neighbouring path (the same level solved on a coarser grid) is
    already the answer when the slip since ``previous`` does not change it. First a
    filter without any product with ``K``: every pair's natural map in its own
    stiffness,

    .. math:: \max_i \max(r_{n,i}, r_{t,i}) \le tol \max|\lambda| ,

    stricter than :func:`qsma.contact.residual.residual` (no round-off allowance);
    a guess that fails it is not checked further. Then the acceptance test of every
    answer, :func:`qsma.contact.residual.measures` on ``problem``: ``(residual,
    force_residual, legacy_residual)`` if ``residual <= tol`` and ``force_residual <=
    FORCE_TOL``, else None (the level is then solved from the guess as before).
    """
    q = pair_quantities(problem, guess.d, guess.lam, previous.d)
    with np.errstate(over="ignore", invalid="ignore"):
        r_n, r_t = natural_map(q, problem.mu, pair_stiffness(problem))
        law = max(r_n.max(initial=0.0), r_t.max(initial=0.0))
    if not law <= tol * reaction_scale(guess.lam):
        return None
    checked = all_measures(problem, lam_w, guess.d, guess.lam, previous)
    return checked if checked[0] <= tol and checked[1] <= FORCE_TOL else None


def accepted_guess(guess):
    """The :class:`Iterate` of a guess that passed :func:`guess_measures`: no
    iteration."""
    return Iterate(np.array(guess.d, dtype=float), np.array(guess.lam, dtype=float), 0, True,
                   "converged: the starting guess meets the check of this level")


def checked_guess(guess, problem):
    """``guess`` if it is a state of ``problem``'s pairs; else :class:`InputError`."""
    if not isinstance(guess, ContactState):
        raise InputError(f"guess must be a ContactState of the problem's pairs, got "
                         f"{type(guess).__name__}")
    return guess.check_against(problem)


def _guarded(fn, scaled, guess, tol, maxiter, options):
    """Call a method on the scaled problem; numerical errors become a failed Iterate."""
    start = scaled.previous if guess is None else guess
    try:
        out = fn(scaled.problem, scaled.lam_w, scaled.previous, tol=tol, maxiter=maxiter,
                 guess=guess, **options)
    except InputError:
        raise
    except NUMERICAL_ERRORS as err:
        return Iterate(start.d, start.lam, 0, False,
                       f"numerical error: {type(err).__name__}: {err}", True)
    if not (np.all(np.isfinite(out.d)) and np.all(np.isfinite(out.lam))):
        return Iterate(start.d, start.lam, out.nit, False,
                       f"non-finite iterate ({out.message})", True)
    return out


class _Scaled:
    """The level in internal units: forces by ``f``, stiffness by ``k``, both powers of 2.

    Powers of two make the scaling exact (no rounding), so a well-scaled
    problem is solved bit for bit as given, while ``|lam_w| ~ 1e200`` or
    ``K ~ 1e-300`` are brought to order one before any square or product.
    """

    def __init__(self, problem, lam_w, previous):
        self.f = _power_of_two(max(np.abs(lam_w).max(), np.abs(previous.lam).max()))
        self.k = _power_of_two(problem.kappa)
        self.u = self.f / self.k
        self.problem = problem.rescaled(self.k, self.u)
        self.lam_w = lam_w / self.f
        self.previous = self.to_internal(previous)

    def to_internal(self, s):
        return ContactState(s.d / self.u, s.lam / self.f, s.status)

    def guess(self, out):
        """The failed iterate as a starting state, its pairs classified."""
        q = pair_quantities(self.problem, out.d, out.lam, self.previous.d)
        with np.errstate(over="ignore", invalid="ignore"):
            status = classify(q, self.problem.mu, self.problem.kappa)
        return ContactState(out.d, out.lam, status)

    def back(self, out):
        return out._replace(d=out.d * self.u, lam=out.lam * self.f)


def _lookup(method, options):
    if method not in METHODS:
        raise InputError(f"unknown contact method {method!r}; valid: {method_names()}")
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


def _result(problem, lam_w, previous, out, method, tol, fallback=None, scaled=None,
            measures=None):
    """Accept or reject the method's iterate on the public residual and the force check.

    With ``scaled`` (see :class:`_Scaled`), ``out`` is in its internal units: the
    measures (all dimensionless) are evaluated there, where nothing overflows, and
    the result is given in the units of ``problem``.
    """
    if scaled is not None:
        problem, lam_w, previous, internal = (scaled.problem, scaled.lam_w, scaled.previous,
                                              out)
        out = scaled.back(out)
    else:
        internal = out
    if measures is None:
        measures = all_measures(problem, lam_w, internal.d, internal.lam, previous)
    r, r_force, r_legacy = measures
    success = bool(out.converged and r <= tol and r_force <= FORCE_TOL)
    message = out.message
    if out.converged and not success:
        message = (f"{message}; rejected: residual {r:.3e} (tol {tol:.1e}), force check "
                   f"{r_force:.3e} (tol {FORCE_TOL:.0e})")
    outcome = (Outcome.CONVERGED if success else Outcome.REJECTED if out.converged
               else Outcome.NUMERICAL_ERROR if out.numerical_error else Outcome.NOT_CONVERGED)
    state = ContactState(out.d, out.lam, _classify(problem, previous, internal, tol))
    if not success:
        warnings.warn(f"contact method {method!r}: {message} (residual {r:.3e}, tol {tol:.1e})",
                      ContactConvergenceWarning, stacklevel=3)
    return ContactResult(state.d, state.lam, state.status, success, out.nit, float(r), message,
                         method, state, outcome, fallback, r_force, r_legacy)


def _classify(problem, previous, out, tol):
    q = pair_quantities(problem, out.d, out.lam, previous.d)
    with np.errstate(over="ignore", invalid="ignore"):
        return classify(q, problem.mu, problem.kappa, tol * reaction_scale(out.lam))
