"""``"active_set"``: semismooth Newton on the Alart-Curnier function, all pairs at once.

With ``c`` the augmentation (default the stiffness scale ``kappa``), the
augmented forces ``sigma_n = P - c w`` and ``sigma_t = Q - c dv`` split the
pairs into active sets (:func:`qsma.contact.law.augmented_forces`), and the
contact law is ``F(d) = 0`` with, per pair,

.. math::
    F_n = P - \\max(0, \\sigma_n), \\qquad
    F_t = Q - \\mathrm{proj}_{\\mu \\max(0, \\sigma_n)}(\\sigma_t),

``lam = K d + lam_w``. A Newton step with a generalised Jacobian of ``F``
(open: ``F = lam``; stuck: ``F = c (w, dv)``; slipping:
``F_t = Q - mu sigma_n h``, ``h = sigma_t/|sigma_t|``, whose derivative
carries the cone curvature in 3D) is a primal-dual active-set step: the
displacements of the stuck components and the closed normals are fixed and
one dense solve gives the rest (:mod:`qsma.contact.linear`).

Safeguards (ping-pong of active sets, a known failure of semismooth Newton
contact solvers): once an active set repeats, steps are damped by a
backtracking line search on ``|F|^2``; if the line search fails, the
Jacobian is singular or ``maxiter`` is reached, the method stops unconverged
and :func:`qsma.contact.solve` hands over to ``"basket"`` from the current
iterate (unless ``fallback=False``). Success is decided by
:func:`qsma.contact.residual`; the measures of the converged iterate are
handed back with it (one pass over ``K`` per iterate).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import InputError
from .law import augmented_forces, natural_map, pair_quantities, slip_directions_from_forces
from .linear import BlockSystem
from .registry import Iterate, register_method
from .residual import (EPS, ROUNDOFF, measures, pair_stiffness, reaction_scale,
                       residual_components)
from .state import OPEN_CODE as OPEN, SLIPPING_CODE as SLIPPING, STUCK_CODE as STUCK

#: Armijo constant and the smallest step of the damped line search.
ARMIJO, MIN_STEP = 1e-4, 2.0 ** -30
#: Newton steps before the fallback.
NEWTON_STEPS = 50
#: Undamped steps without a new lowest ``|F|`` before damping starts. On the 667-pair
#: Siconos granular-flow problem the undamped iteration wandered through new active
#: sets (no exact repeat) for all 50 steps; with damping after 5 stalled steps it
#: converges in 17 (benchmarks/bench_contact_corpus.py). 5: long enough not to damp
#: the ordinary non-monotone first steps of a ramp level (the warm-started ramps of
#: tests/contact/test_contact_convergence.py keep their iteration counts).
STALL_STEPS = 5


@register_method("active_set")
def solve_active_set(problem, lam_w, previous, *, tol, maxiter=None, guess=None,
                     augmentation=1.0):
    """Semismooth Newton / primal-dual active set with cycling safeguards.

    Parameters
    ----------
    augmentation : float
        ``c = augmentation * kappa`` in ``sigma_n = P - c w``,
        ``sigma_t = Q - c dv``.
    maxiter : int, optional
        Cap on the iterations of the solve, fallback included: at most
        ``min(maxiter, 50)`` Newton steps, the rest for the fallback.
    guess : ContactState, optional
        Starting iterate (default ``previous``). The first step holds the active
        sets of the starting iterate's pair states: for a guess that is the
        answer of a neighbouring path (the same point of the cycle before, in a
        computed loop) they are nearly this level's.
    """
    if not (np.isscalar(augmentation) and np.isfinite(augmentation) and augmentation > 0):
        raise InputError(f"augmentation must be a positive number, got {augmentation!r}")
    steps = NEWTON_STEPS if maxiter is None else min(maxiter, NEWTON_STEPS)
    newton = _Newton(problem, lam_w, previous, augmentation * problem.kappa, guess)
    for it in range(steps + 1):
        checked = newton.accepted(lam_w, previous, tol)
        if checked is not None:
            return Iterate(newton.d2, newton.lam2, it, True,
                           f"converged in {it} Newton steps{newton.note()}", measures=checked)
        if it == steps or not newton.step():
            break
    reason = (newton.failure or f"no convergence in {it} Newton steps") + newton.note()
    return Iterate(newton.d2, newton.lam2, it, False, reason)


def _previous_sets(previous):
    """``(status, h)`` of a state (the previous one or a guess), or None if every pair
    is stuck in it."""
    if np.all(previous.status == STUCK):
        return None
    return previous.status.copy(), -slip_directions_from_forces(previous.lam[:, :-1],
                                                                 previous.status)


class ActiveSets(NamedTuple):
    """Alart-Curnier active sets of an iterate.

    ``status`` (n,) open / stuck / slipping, ``h`` (n, m) unit ``sigma_t``,
    ``alpha`` (n,) ``mu sigma_n / |sigma_t|`` (slipping pairs; 0 elsewhere),
    ``F`` (n, dim) the Alart-Curnier function.
    """

    status: np.ndarray
    h: np.ndarray
    alpha: np.ndarray
    F: np.ndarray


class _Newton:
    """Iterate and safeguards of the semismooth Newton method."""

    def __init__(self, problem, lam_w, previous, c, guess=None):
        self.problem, self.lw, self.prev, self.c = problem, lam_w.ravel(), previous.d, c
        start = previous if guess is None else guess
        self.d = np.array(start.d, dtype=float).ravel()
        self._set_force()
        self.seen, self.damped, self.failure = set(), False, None
        self.best, self.stall = np.inf, 0
        self.first = _previous_sets(start)
        self.system = None       # BlockSystem of the pair states of the last step

    @property
    def d2(self):
        return self.d.reshape(-1, self.problem.dim)

    @property
    def lam2(self):
        return self.lam.reshape(-1, self.problem.dim)

    def accepted(self, lam_w, previous, tol):
        """The measures of the current iterate if it passes the residual check of every
        answer (:func:`qsma.contact.residual.residual` ``<= tol``), else None.

        An iterate that :func:`surely_rejected` rejects is not checked further: the
        product with ``|K|`` of the check is formed only for iterates that may pass (``K
        d`` is the iterate's own, :meth:`_set_force`), and the decision is the check's
        own."""
        problem = self.problem
        if surely_rejected(problem, lam_w, self.d2, self.lam2, self.prev, tol):
            return None
        with np.errstate(over="ignore", invalid="ignore"):
            Kd_aKd = self.Kd, problem.abs_product(self.d, symmetric=True)
        r = residual_components(problem, lam_w, self.d2, self.lam2, previous,
                                known_products=Kd_aKd).total
        if not r <= tol:
            return None
        return measures(problem, lam_w, self.d2, self.lam2, previous, known_products=Kd_aKd,
                        known_residual=r)

    def note(self):
        return "; cycling or stall detected, damped steps" if self.damped else ""

    def sets(self, d=None, lam=None, imposed=None):
        """Active sets and ``F`` at ``(d, lam)`` (default: the current iterate)."""
        d = self.d2 if d is None else d.reshape(self.d2.shape)
        lam = self.lam2 if lam is None else lam.reshape(self.d2.shape)
        q = pair_quantities(self.problem, d, lam, self.prev)
        return alart_curnier_sets(q, self.problem.mu, self.c, *(imposed or ()))

    def step(self):
        """One Newton step (damped after a cycle); False if it cannot proceed.

        The first step holds the sets of the starting state (the previous
        converged state or the guess: the warm start), later ones take the sets
        of the augmented forces.
        """
        if self.first is not None:
            sets, self.first = self.sets(imposed=self.first), None
        else:
            sets = self.sets()
            self._watch_cycle(sets)
        try:
            target = self._newton_point(sets)
        except np.linalg.LinAlgError:
            self.failure = "singular generalised Jacobian"
            return False
        t = self._line_search(sets, target - self.d) if self.damped else 1.0
        if t is None:
            self.failure = "line search found no decrease of |F|"
            return False
        self.d = self.d + t * (target - self.d)
        self._set_force()
        return True

    def _set_force(self):
        """``lam = K d + lam_w`` of the iterate, ``K d`` kept for its check (one
        product of one triangle, :meth:`qsma.contact.ContactProblem.product`)."""
        with np.errstate(over="ignore", invalid="ignore"):
            self.Kd = self.problem.product(self.d)
        self.lam = self.Kd + self.lw

    def _watch_cycle(self, sets):
        """Damp from now on if an active set repeats, or if ``|F|`` has not gone below
        its best value for :data:`STALL_STEPS` steps (a wander through ever new sets)."""
        key = sets.status.tobytes() + (sets.h > 0).tobytes()
        if key in self.seen:
            self.damped = True
        self.seen.add(key)
        merit = float(np.sum(sets.F ** 2))
        if merit < self.best:
            self.best, self.stall = merit, 0
        else:
            self.stall += 1
            self.damped |= self.stall >= STALL_STEPS

    def _newton_point(self, sets):
        """Full Newton step: ``J d_new = J d - F`` with the fixed components known.

        On the stuck components and closed normals ``J = c I`` and the step
        lands on ``d_t = d_t,prev``, ``d_n = -g0``; on open pairs ``J = K``
        and ``J d - F = -lam_w``; on slipping pairs the rows are those of
        :func:`qsma.contact.linear.slip_rows` with ``s = -h``.
        """
        system = self.system
        if system is None or not np.array_equal(system.status, sets.status):
            system = self.system = BlockSystem(self.problem, self.lw, sets.status, self.prev)
        return system.solve(-sets.h, sets.alpha, self.c)

    def _line_search(self, sets, delta):
        """Backtracking on ``|F|^2`` along ``delta``; the step length or None."""
        merit0 = np.sum(sets.F ** 2)
        K_delta, t = self.problem.K @ delta, 1.0
        while t >= MIN_STEP:
            F = self.sets(self.d + t * delta, self.lam + t * K_delta).F
            if np.sum(F ** 2) <= (1.0 - 2.0 * ARMIJO * t) * merit0:
                return t
            t *= 0.5
        return None


def surely_rejected(problem, lam_w, d, lam, d_prev, tol):
    r"""Whether ``(d, lam)`` fails the residual check ``residual <= tol`` for certain,
    decided without a product with ``K``.

    The check fails when a pair's natural map in its own stiffness, less its round-off
    allowance ``a_i``, exceeds ``tol max|lam|`` (:func:`qsma.contact.residual.residual`).
    ``a_i`` is bounded above through the row sums of ``|K|``,
    ``(|K| |d|)_j <= \sum_k |K_{jk}| \max|d|``, taken twice for the rounding of the
    products (``|K| |d|`` in single precision on large problems errs by far less). So a
    pair with ``r_i - 2 a_i^{max} > tol max|lam|`` fails the check whatever ``|K| |d|``
    is; NaN never counts as certain (the check itself then judges).
    """
    q = pair_quantities(problem, d, lam, d_prev)
    with np.errstate(over="ignore", invalid="ignore"):
        r_n, r_t = natural_map(q, problem.mu, pair_stiffness(problem))
        top = np.abs(d).max(initial=0.0)
        terms = problem.abs_row_sums * top + np.abs(lam_w.ravel())
        a_max = 2.0 * ROUNDOFF * np.sqrt(problem.size) * EPS * \
            terms.reshape(problem.n_pairs, -1).max(axis=1)
        excess = np.maximum(r_n, r_t) - a_max
        return bool(excess.max(initial=-np.inf) > (1.0 + 2.0 ** -20) * tol
                    * reaction_scale(lam))


def alart_curnier_sets(q, mu, c, status=None, h=None):
    """Active sets and the Alart-Curnier function of every pair (:class:`ActiveSets`).

    The sets are those of the augmented forces unless ``status`` and ``h``
    (unit slip force direction of slipping pairs) are imposed; then
    ``alpha = 0`` (the direction is held for the step).
    """
    a = augmented_forces(q, mu, c)
    if status is None:
        status = np.where(~a.closed, OPEN, np.where(a.stick, STUCK, SLIPPING))
        norm = np.linalg.norm(a.sigma_t, axis=1)
        slip = status == SLIPPING
        h = np.zeros_like(a.sigma_t)
        h[slip] = a.sigma_t[slip] / norm[slip, None]
        alpha = np.where(slip, mu * a.sigma_n / np.maximum(norm, 1e-300), 0.0)
    else:
        alpha = np.zeros(len(status))
    return ActiveSets(status, h, alpha, _alart_curnier_function(q, a, status, h, mu, c))


def _alart_curnier_function(q, a, status, h, mu, c):
    """``F`` of each pair on its set: open ``lam``; stuck ``c (dv, w)``;
    slipping ``(Q - mu sigma_n h, c w)``."""
    F = np.empty((len(status), q.Q.shape[1] + 1))
    F[:, -1] = np.where(status != OPEN, c * q.w, q.P)
    F[:, :-1] = np.where((status == OPEN)[:, None], q.Q,
                         np.where((status == STUCK)[:, None], c * q.dv,
                                  q.Q - (mu * a.sigma_n)[:, None] * h))
    return F
