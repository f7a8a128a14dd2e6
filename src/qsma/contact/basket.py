"""``"basket"``: block Gauss-Seidel with stuck / slipping / open baskets (method.md section 5).

Pairs sit in baskets by state, each temporary or final. One iteration is a
block step (:mod:`qsma.contact.linear`) followed by the state checks of
:func:`qsma.contact.law.basket_transitions` on the temporary pairs; a pair
confirmed twice in a row (or never moved) goes to its final basket and is
not rechecked in this pass. A pass ends when no pair moves and the
displacements of the slipping and open pairs have settled; the final
baskets then become temporary again and every pair is rechecked, until a
pass moves nothing. The answer is accepted on :func:`qsma.contact.residual`.

Block step (``coupling``):

* ``"joint"`` (default): one dense solve for the unknowns of the slipping
  and the open baskets together (the stuck basket is explicit, its ``d`` is
  known). On an ill-conditioned K this is what makes the method converge in
  a handful of iterations; see docs/contact.md.
* ``"gauss_seidel"``: the literal scheme, one basket after the other (stuck,
  slipping, open), each solve holding the other baskets' displacements; the
  relative change of displacement (paper eq. 19) decides when it has
  settled.

A failed check sends a pair to the basket its one-pair solution allows
(:func:`qsma.contact.law.local_states`). If a configuration of baskets
comes back (a cycle), pairs move one at a time, each time to a
configuration not yet visited.

In 3D the slip direction of a slipping pair is a continuous unknown: with
the baskets held, the block step is repeated as a damped Newton iteration
on the slip law (direction ``-(Q - kappa dv)/|Q - kappa dv|``, the
projection on the friction disk; rows of
:func:`qsma.contact.linear.slip_rows`) until the slip law holds, and only
then are the baskets checked ("the algorithm cycles over the basket until
the governing equations at all basket nodes are satisfied"). If no
direction satisfies it (the line search fails), the slipping pair of
largest misfit fails its check and goes to the stuck basket. In 2D the
direction is a sign and one block step is exact.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import InputError
from .law import (basket_transitions, local_states, pair_quantities, row_norm,
                  slip_directions_from_forces)
from .linear import BlockSystem, known_displacement, open_rows, slip_rows, solve_partitioned
from .registry import Iterate, register_method
from .residual import measures, reaction_scale, roundoff_allowance
from .state import OPEN_CODE as OPEN, SLIPPING_CODE as SLIPPING, STUCK_CODE as STUCK

#: Checks ignore violations below this fraction of ``tol * F``, so that
#: round-off cannot move a pair back and forth; they then add at most
#: ``0.01 tol`` to the residual.
CHECK_FRACTION = 0.01
COUPLINGS = ("joint", "gauss_seidel")
#: 3D: Newton steps on the slip directions per basket configuration, and the
#: Armijo constant and smallest step of their line search.
DIRECTION_STEPS, ARMIJO, MIN_STEP = 30, 1e-4, 2.0 ** -20
#: 3D: the slip law is taken as not met (the pair of largest misfit goes to the
#: stuck basket) when the line search needs a step below SHORT_STEP, or when the
#: misfit shrinks by less than a factor SLOW_RATE per step for SLOW_STEPS steps in a
#: row. Measured on the 356-contact FCLIB problem Spheres-i099-356-679: pairs whose
#: line search ended at steps of 2^-5 to 2^-19 never recovered (14 and 10 block
#: steps spent for nothing), and a pair whose slip length went to zero (stuck at
#: the cone) converged at a rate 0.58 per step for 29 steps before being moved.
SHORT_STEP, SLOW_RATE, SLOW_STEPS = 2.0 ** -4, 0.5, 3


@register_method("basket")
def solve_basket(problem, lam_w, previous, *, tol, maxiter=None, guess=None, coupling="joint",
                 pass_tol=None):
    """Block Gauss-Seidel with baskets.

    Parameters
    ----------
    coupling : {"joint", "gauss_seidel"}
        Block step, see the module docstring.
    pass_tol : float, optional
        Relative change of displacement at slipping and open pairs below
        which a pass has settled (paper eq. 19); default ``tol``.
    maxiter : int, optional
        Cap on block steps (default 200 for ``"joint"``, 20000 for
        ``"gauss_seidel"``).
    guess : ContactState, optional
        Initial baskets and iterate (default ``previous``).
    """
    return run_baskets(problem, lam_w, previous, tol=tol, maxiter=maxiter, coupling=coupling,
                       pass_tol=pass_tol, guess=guess)


def run_baskets(problem, lam_w, previous, *, tol, maxiter=None, coupling="joint",
                pass_tol=None, guess=None):
    """The basket iteration, optionally started from another iterate.

    Parameters
    ----------
    guess : ContactState, optional
        Initial baskets (``status``), displacement and slip directions (from
        ``lam``); default ``previous``. The slip reference is always
        ``previous``.

    Returns
    -------
    Iterate
        ``nit`` counts block steps (linear solves).
    """
    if coupling not in COUPLINGS:
        raise InputError(f"coupling must be one of {COUPLINGS}, got {coupling!r}")
    maxiter = maxiter or (200 if coupling == "joint" else 20000)
    run = _BasketRun(problem, lam_w, previous, guess or previous, coupling, tol,
                     pass_tol or tol, maxiter)
    while run.solves < maxiter:
        verdict = run.iterate()
        if verdict is not None:
            converged, message, checked = verdict
            return Iterate(run.d2, run.lam2, run.solves, converged, message, measures=checked)
    return Iterate(run.d2, run.lam2, run.solves, False,
                   f"no convergence in maxiter={maxiter} block steps ({run.summary()})")


class _BasketRun:
    """Mutable working state of one basket solve (baskets, iterate, history)."""

    def __init__(self, problem, lam_w, previous, guess, coupling, tol, pass_tol, maxiter):
        self.problem, self.lam_w, self.previous = problem, lam_w, previous
        self.lw, self.prev = lam_w.ravel(), previous.d
        self.coupling, self.tol, self.pass_tol, self.maxiter = coupling, tol, pass_tol, maxiter
        n = problem.n_pairs
        self.status = np.array(guess.status)
        self.direction = slip_directions_from_forces(guess.lam[:, :-1], self.status)
        undirected = (self.status == SLIPPING) & ~self.direction.any(axis=1)
        self.status[undirected] = STUCK          # no slip direction to hold: recheck
        self.alpha = np.zeros(n)
        self.final = np.zeros(n, bool)
        self.confirmed = np.zeros(n, int)
        self.ever_moved = np.zeros(n, bool)
        self.d = np.array(guess.d, dtype=float).ravel()
        self._lam = self._Kd = self._abs_Kd = None   # of the current iterate
        self._threshold_of = None                # threshold of the current iterate
        self._system = None                      # BlockSystem of the current baskets
        self.cautious, self.solves, self.quiet = False, 0, 0
        self.seen = {self._key(self.status, self.direction)}

    @property
    def d2(self):
        return self.d.reshape(-1, self.problem.dim)

    @property
    def lam(self):
        self._kd()
        return self._lam

    def _kd(self):
        """``K d`` of the current iterate, formed once (with ``lam = K d + lw``)."""
        if self._lam is None:
            self._Kd = self.problem.product(self.d)
            self._lam = self._Kd + self.lw
        return self._Kd

    def _products(self):
        """``(K d, |K| |d|)`` of the current iterate, each formed once (the threshold of
        the checks and the residual of the end of a pass share them)."""
        if self._abs_Kd is None:
            self._abs_Kd = self.problem.abs_product(self.d, symmetric=True)
        return self._kd(), self._abs_Kd

    @property
    def lam2(self):
        return self.lam.reshape(-1, self.problem.dim)

    def summary(self):
        counts = np.bincount(self.status, minlength=3)
        return (f"stuck={counts[STUCK]}, slipping={counts[SLIPPING]}, open={counts[OPEN]}"
                f"{', cycling detected' if self.cautious else ''}")

    def iterate(self):
        """Block step(s) and state check; ``(converged, message, measures or None)`` when
        done (the measures of the final iterate, see :class:`Iterate`)."""
        try:
            if self.solves == 0:
                self._linearised_start()
            d_new = self._block_step()
            change = self._relative_change(d_new) if self.coupling == "gauss_seidel" else 0.0
            self._set_iterate(d_new)
            unsettled = None
            if self.problem.dim == 3 and self.coupling == "joint":
                change, unsettled = self._settle_directions()
        except np.linalg.LinAlgError:
            return False, f"singular block system ({self.summary()})", None
        q = pair_quantities(self.problem, self.d2, self.lam2, self.prev)
        threshold = self._threshold()
        tr = basket_transitions(
            self.status, self.direction, q, self.problem.mu, self.problem.kappa, threshold,
            lambda pairs: local_states(self.problem, self.d2, self.lam2, self.prev,
                                       threshold[pairs], pairs))
        if unsettled is not None and tr.status[unsettled[0]] == SLIPPING:
            tr.status[unsettled[0]] = STUCK       # no slip direction satisfies the law
            tr.violation[unsettled[0]] = unsettled[1]
            self.final[unsettled[0]] = False      # moved even from a final basket
        if self._move(tr, temporary=~self.final):
            self.quiet = 0
            return None
        self.quiet += 1
        self._update_directions(q)
        if change > self.pass_tol:
            return self._accepted_early(tr)
        stalled = self.quiet >= 2 if self.coupling == "joint" else change == 0.0
        return self._end_of_pass(tr, stalled)

    def _linearised_start(self):
        """3D, joint coupling, before the first block step of a solve: the slipping
        pairs' slip directions and cone curvature ``alpha`` from the slip law at the
        starting iterate (:meth:`_slip_law`), so that the first step already is a
        Newton step on the directions, instead of the directions of the starting forces
        with ``alpha = 0``. Measured on the 586 solves of sandwich-3d refine 1: 2302 ->
        1917 block steps, the same states and answers to 6e-13 of their largest value."""
        slip = self.status == SLIPPING
        if self.problem.dim == 3 and self.coupling == "joint" and slip.any():
            self.direction[slip], self.alpha[slip], _ = self._slip_law(self.d, self.lam)

    def _threshold(self):
        """Per pair, the violation a check ignores (force units): a fraction of what
        the residual allows, ``CHECK_FRACTION tol max|lam|``, plus the round-off
        allowance of the pair's force (:func:`qsma.contact.residual.roundoff_allowance`)."""
        if self._threshold_of is None:            # reset with each new iterate
            self._threshold_of = (CHECK_FRACTION * self.tol * reaction_scale(self.lam)
                                  + roundoff_allowance(self.problem, self.lam_w, self.d2,
                                                       self._products()[1]))
        return self._threshold_of

    def _set_iterate(self, d, Kd=None):
        """A new iterate ``d``; ``Kd``, optional: its product ``K d`` if already formed."""
        self.d, self._lam, self._Kd, self._abs_Kd, self._threshold_of = d, None, Kd, None, None
        if Kd is not None:
            self._lam = Kd + self.lw

    def _accepted_early(self, tr):
        """The verdict on a 3D iterate whose slip directions have settled but whose last
        Newton step still moved ``d`` by more than ``pass_tol``, when every pair, final
        basket or not, passes its check (``tr``): converged if the iterate meets the
        residual, else None (the pass goes on as before). Without it the pass took one
        more block step only to see ``d`` not move."""
        if self.coupling != "joint" or np.any(tr.status != self.status):
            return None
        checked = measures(self.problem, self.lam_w, self.d2, self.lam2, self.previous,
                           self._products())
        if checked[0] <= self.tol:
            return True, f"converged: no pair changed basket ({self.summary()})", checked
        return None

    def _end_of_pass(self, tr, stalled):
        """Reopen the final baskets and recheck them; accept on the residual."""
        if self.final.any():
            self.final[:] = False
            self.confirmed[:] = 0
            if self._move(tr, temporary=np.ones_like(self.final)):
                return None
        checked = measures(self.problem, self.lam_w, self.d2, self.lam2, self.previous,
                           self._products())
        r = checked[0]
        if r <= self.tol:
            return True, f"converged: no pair changed basket ({self.summary()})", checked
        if stalled:
            return (False, f"baskets settled but residual {r:.3e} > tol ({self.summary()})",
                    checked)
        return None

    # -- baskets -------------------------------------------------------------

    def _move(self, tr, temporary):
        """Move the temporary pairs that failed their check; True if any moved.

        All failed pairs move at once, unless that returns to a configuration
        of baskets seen before in this solve (a cycle): from then on one pair
        moves per step, the most violated one whose move (to its proposed
        basket, or else to another) leads somewhere new.
        """
        wants = (tr.status != self.status) & temporary
        self.confirmed = np.where(wants, 0, self.confirmed + temporary)
        self.final |= temporary & ~wants & (~self.ever_moved | (self.confirmed >= 2))
        if not wants.any():
            return False
        status, direction = np.where(wants, tr.status, self.status), self.direction.copy()
        direction[wants] = tr.direction[wants]
        if self.cautious or self._key(status, direction) in self.seen:
            self.cautious = True
            status, direction = self._new_single_move(tr, wants, status, direction)
        self.ever_moved |= status != self.status
        self.alpha[status != self.status] = 0.0
        self.status, self.direction = status, direction
        self.seen.add(self._key(status, direction))
        return True

    def _new_single_move(self, tr, wants, fallback_status, fallback_direction):
        """The most violated single move to an unseen configuration; if every move of
        the failed pairs leads back to a seen one, a move of another pair (in index
        order) to an unseen configuration; else all moves.

        The second rule matters when the answer needs a pair that passes its check
        to change: on a 2-pair 2D problem (cond 5e7, mu 1.17) the failed pair went
        back and forth between two seen configurations for 200 block steps while
        the only solution had the other pair open.
        """
        ranked = np.argsort(-np.where(wants, tr.violation, -np.inf))[:np.count_nonzero(wants)]
        for i in np.concatenate([ranked, np.flatnonzero(~wants)]):
            proposed = tr.status[i] if wants[i] else self.status[i]
            toward = self._slip_guess(i, tr.direction[i])
            for code, sign in self._targets(i, proposed):
                status, direction = self.status.copy(), self.direction.copy()
                status[i] = code
                direction[i] = sign * toward
                if self._key(status, direction) not in self.seen:
                    return status, direction
        return fallback_status, fallback_direction

    def _slip_guess(self, i, direction):
        """``direction`` if it is a unit vector, else ``-Q_i/|Q_i|`` (else the first
        tangent axis): a slip direction for a pair sent to slip without one."""
        if np.any(direction):
            return direction
        Q = self.lam2[i, :-1]
        size = np.linalg.norm(Q)
        return -Q / size if size > 0 else np.eye(len(Q))[0]

    def _targets(self, i, proposed):
        """Baskets to try for pair ``i``: the proposed one first, then the others."""
        others = [c for c in (STUCK, SLIPPING, OPEN) if c not in (proposed, self.status[i])]
        out = [(c, 1.0) for c in [proposed] + others]
        if self.problem.dim == 2:
            out.append((SLIPPING, -1.0))
        return out

    def _key(self, status, direction):
        """A configuration: baskets, and in 2D the slip signs."""
        if self.problem.dim == 3:
            return status.tobytes()
        return status.tobytes() + np.where(status == SLIPPING, direction[:, 0] > 0,
                                           False).tobytes()

    # -- block steps ---------------------------------------------------------

    def _block_step(self):
        self.solves += 1
        if self.coupling == "joint":
            if self._system is None or not np.array_equal(self._system.status, self.status):
                self._system = BlockSystem(self.problem, self.lw, self.status, self.prev)
            return self._system.solve(self.direction, self.alpha, self.problem.kappa)
        return self._gauss_seidel_step()

    def _gauss_seidel_step(self):
        """Literal block Gauss-Seidel: slipping basket, then open basket."""
        p, st = self.problem, self.status
        d = np.where(_known_mask(p, st), known_displacement(p, st, self.prev), self.d)
        slip, opened = np.flatnonzero(st == SLIPPING), np.flatnonzero(st == OPEN)
        R, b = slip_rows(p, self.lw, slip, self.direction[slip], self.alpha[slip],
                         self.prev[slip, :-1], p.kappa)
        d = solve_partitioned(R, b, p.tangent_index[slip].ravel(), d)
        R, b = open_rows(p, self.lw, opened)
        return solve_partitioned(R, b, (opened[:, None] * p.dim + np.arange(p.dim)).ravel(), d)

    def _relative_change(self, d_new):
        """Paper eq. 19: max change at slipping/open pairs relative to their displacement."""
        moving = np.repeat(self.status != STUCK, self.problem.dim)
        if not moving.any():
            return 0.0
        delta = np.max(np.abs(d_new[moving] - self.d[moving]))
        size = np.max(np.abs(d_new[moving] - self.prev.ravel()[moving]))
        return float(delta / max(size, np.finfo(float).tiny))

    # -- slip directions (3D) ------------------------------------------------

    def _slip_law(self, d, lam=None):
        """Augmented slip directions at ``d`` and the slip-law misfit of slipping pairs.

        Returns ``(s, alpha, misfit)`` for the slipping pairs:
        ``s = -sigma_t/|sigma_t|`` with ``sigma_t = Q - kappa dv``,
        ``alpha = mu P / |sigma_t|`` (clipped to [0, 1]) and
        ``|Q + mu P s|^2`` (the rows of the block step, linear in ``P``: no
        clipping of ``P``).
        """
        slip = np.flatnonzero(self.status == SLIPPING)
        dim = self.problem.dim
        lam = self.problem.product(d) + self.lw if lam is None else lam
        lam2, d2 = lam.reshape(-1, dim)[slip], d.reshape(-1, dim)[slip]
        Q = lam2[:, :-1]
        sigma = Q - self.problem.kappa * (d2[:, :-1] - self.prev[slip, :-1])
        norm = np.maximum(row_norm(sigma), np.finfo(float).tiny)
        s = -sigma / norm[:, None]
        mu_p = self.problem.mu[slip] * lam2[:, -1]
        misfit = np.sum((Q + mu_p[:, None] * s) ** 2, axis=1)
        return s, np.clip(mu_p / norm, 0.0, 1.0), misfit

    def _settle_directions(self):
        """Damped Newton on the 3D slip law with the baskets held.

        Returns the relative change of displacement of the last step (0 if
        the slip law already held) and, if the slip law is not being met, the
        slipping pair of largest misfit and the misfit (force units), else
        None. Not being met: the line search needs a step below
        :data:`SHORT_STEP` (no slip direction nearby satisfies the law), or
        the misfit has shrunk by less than :data:`SLOW_RATE` per step for
        :data:`SLOW_STEPS` steps (linear convergence: the slip length of a
        pair is going to zero, i.e. the pair is stuck at the cone).
        """
        slip = self.status == SLIPPING
        change, slow, previous, law = 0.0, 0, np.inf, None
        for _ in range(DIRECTION_STEPS):
            s, alpha, misfit = law or self._slip_law(self.d, self.lam)
            goal = self._threshold()[slip]
            if not slip.any() or np.all(np.sqrt(misfit) <= goal) or self.solves >= self.maxiter:
                return change, None
            size = np.sqrt(misfit.sum())
            slow = slow + 1 if size > SLOW_RATE * previous else 0
            worst = np.argmax(misfit)
            stuck_pair = (np.flatnonzero(slip)[worst], float(np.sqrt(misfit[worst])))
            if slow >= SLOW_STEPS:
                return change, stuck_pair
            previous = size
            self.direction[slip], self.alpha[slip] = s, alpha
            step = self._line_search(self._block_step(), misfit.sum())
            if step is None or step.t < SHORT_STEP:
                return change, stuck_pair
            change = self._relative_change(step.d)
            self._set_iterate(step.d, step.Kd)
            law = step.law
        return change, None

    def _line_search(self, target, misfit0):
        """Armijo backtracking on the slip-law misfit from the iterate towards ``target``
        (the block step); the accepted :class:`_Step` or None below :data:`MIN_STEP`.

        The full step is tried first at ``target`` itself with ``K target``, the one
        product of the Newton step: an accepted full step hands its ``K d`` and its slip
        law to the next Newton step (no second product, no second evaluation). A
        shorter step keeps no product (the next Newton step forms ``K d`` of its
        iterate), so every ``K d`` of an iterate is a product of that very ``d``."""
        K_target = self.problem.product(target)
        law = self._slip_law(target, K_target + self.lw)
        if law[2].sum() <= (1.0 - 2.0 * ARMIJO) * misfit0:
            return _Step(1.0, target, K_target, law)
        delta, K_delta, t = target - self.d, K_target - self._kd(), 0.5
        while t >= MIN_STEP:
            trial = self._slip_law(self.d + t * delta, self.lam + t * K_delta)[2].sum()
            if trial <= (1.0 - 2.0 * ARMIJO * t) * misfit0:
                return _Step(t, self.d + t * delta, None, None)
            t *= 0.5
        return None

    def _update_directions(self, q):
        """Literal scheme in 3D: pairs that stay slipping turn to ``-(Q - kappa dv)``."""
        if self.problem.dim == 2 or self.coupling == "joint":
            return                   # 2D: a passed check keeps the sign; joint 3D: settled
        slipping = self.status == SLIPPING
        sigma = q.Q - self.problem.kappa * q.dv
        size = row_norm(sigma)
        ok = slipping & (size > 0)
        self.direction[ok] = -sigma[ok] / size[ok, None]
        self.alpha[ok] = np.clip(self.problem.mu[ok] * q.P[ok] / size[ok], 0.0, 1.0)


class _Step(NamedTuple):
    """An accepted step of the slip-direction line search: its length ``t``, the new
    iterate ``d``, and for a full step (``t = 1``) its ``K d`` and slip law
    (:meth:`_BasketRun._slip_law`), else None."""

    t: float
    d: np.ndarray
    Kd: np.ndarray | None
    law: tuple | None


def _known_mask(problem, status):
    mask = np.zeros((problem.n_pairs, problem.dim), bool)
    mask[status == STUCK] = True
    mask[status == SLIPPING, -1] = True
    return mask.ravel()
