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

In 3D the slip direction of a slipping pair is updated to its slip increment
direction after every step, and the block step uses the curvature of the
cone (a Newton step on the direction; exact in 2D).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .law import (basket_transitions, local_states, pair_quantities,
                  slip_directions_from_forces)
from .linear import basket_system, known_displacement, open_rows, slip_rows, solve_partitioned
from .registry import Iterate, register_method
from .residual import force_scale, residual
from .state import OPEN, SLIPPING, STUCK

#: Checks ignore violations below this fraction of ``tol * F``, so that
#: round-off cannot move a pair back and forth; they then add at most
#: ``0.01 tol`` to the residual.
CHECK_FRACTION = 0.01
COUPLINGS = ("joint", "gauss_seidel")


@register_method("basket")
def solve_basket(problem, lam_w, previous, *, tol, maxiter=None, coupling="joint",
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
        Block steps; default 200 (``"joint"``) or 20000 (``"gauss_seidel"``).
    """
    return run_baskets(problem, lam_w, previous, tol=tol, maxiter=maxiter, coupling=coupling,
                       pass_tol=pass_tol)


def run_baskets(problem, lam_w, previous, *, tol, maxiter=None, coupling="joint",
                pass_tol=None, guess=None):
    """The basket iteration, optionally started from another iterate.

    Parameters
    ----------
    guess : ContactState, optional
        Initial baskets (``status``) and slip directions (from ``lam``);
        default ``previous``. The slip reference is always ``previous``.

    Returns
    -------
    Iterate
    """
    if coupling not in COUPLINGS:
        raise InputError(f"coupling must be one of {COUPLINGS}, got {coupling!r}")
    maxiter = maxiter or (200 if coupling == "joint" else 20000)
    run = _BasketRun(problem, lam_w, previous, guess or previous, coupling, tol,
                     pass_tol or tol)
    for it in range(1, maxiter + 1):
        verdict = run.iterate()
        if verdict is not None:
            return Iterate(run.d2, run.lam2, it, verdict[0], verdict[1])
    return Iterate(run.d2, run.lam2, maxiter, False,
                   f"no convergence in maxiter={maxiter} block steps ({run.summary()})")


class _BasketRun:
    """Mutable working state of one basket solve (baskets, iterate, history)."""

    def __init__(self, problem, lam_w, previous, guess, coupling, tol, pass_tol):
        self.problem, self.lw, self.prev = problem, lam_w.ravel(), previous.d
        self.lam_w, self.previous = lam_w, previous
        self.coupling, self.tol, self.pass_tol = coupling, tol, pass_tol
        n, m = problem.n_pairs, problem.dim - 1
        self.status = np.array(guess.status)
        self.direction = slip_directions_from_forces(guess.lam[:, :-1], self.status)
        self.curvature = np.zeros(n)
        self.final = np.zeros(n, bool)
        self.confirmed = np.zeros(n, int)
        self.ever_moved = np.zeros(n, bool)
        self.d = np.array(guess.d, dtype=float).ravel()
        self.lam = problem.K @ self.d + self.lw
        self.cautious, self.m = False, m
        self.seen = {self._key(self.status, self.direction)}

    @property
    def d2(self):
        return self.d.reshape(-1, self.problem.dim)

    @property
    def lam2(self):
        return self.lam.reshape(-1, self.problem.dim)

    def summary(self):
        counts = np.bincount(self.status, minlength=3)
        return (f"stuck={counts[STUCK]}, slipping={counts[SLIPPING]}, open={counts[OPEN]}"
                f"{', cycling detected' if self.cautious else ''}")

    def iterate(self):
        """One block step and state check; ``(converged, message)`` when done."""
        try:
            d_new = self._block_step()
        except np.linalg.LinAlgError:
            return False, f"singular block system ({self.summary()})"
        change = self._relative_change(d_new)
        self.d = d_new
        self.lam = self.problem.K @ d_new + self.lw
        q = pair_quantities(self.problem, self.d2, self.lam2, self.prev)
        threshold = CHECK_FRACTION * self.tol * force_scale(self.lw, self.lam)
        local = local_states(self.problem, self.d2, self.lam2, self.prev, threshold)
        tr = basket_transitions(self.status, self.direction, q, self.problem.mu,
                                self.problem.kappa, threshold, local)
        turned = self._direction_change(tr)
        self._update_directions(tr, q)
        if self._move(tr, temporary=~self.final):
            return None
        settled = change <= self.pass_tol or (self.coupling == "joint" and turned <= self.pass_tol)
        if not settled:
            return None
        return self._end_of_pass(tr, stalled=(change == 0.0))

    def _end_of_pass(self, tr, stalled):
        """Reopen the final baskets and recheck them; accept on the residual."""
        if self.final.any():
            self.final[:] = False
            self.confirmed[:] = 0
            if self._move(tr, temporary=np.ones_like(self.final)):
                return None
        r = residual(self.problem, self.lam_w, self.d2, self.lam2, self.previous)
        if r <= self.tol:
            return True, f"converged: no pair changed basket ({self.summary()})"
        if stalled:
            return False, f"baskets settled but residual {r:.3e} > tol ({self.summary()})"
        return None

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
        self.curvature[status != self.status] = 0.0
        self.status, self.direction = status, direction
        self.seen.add(self._key(status, direction))
        return True

    def _new_single_move(self, tr, wants, fallback_status, fallback_direction):
        """The most violated single move to an unseen configuration (else all moves)."""
        for i in np.argsort(-np.where(wants, tr.violation, -np.inf))[:np.count_nonzero(wants)]:
            for code, sign in self._targets(i, tr.status[i]):
                status, direction = self.status.copy(), self.direction.copy()
                status[i] = code
                direction[i] = sign * tr.direction[i]
                if self._key(status, direction) not in self.seen:
                    return status, direction
        return fallback_status, fallback_direction

    def _targets(self, i, proposed):
        """Baskets to try for pair ``i``: the proposed one first, then the others."""
        order = [proposed] + [c for c in (STUCK, SLIPPING, OPEN) if c not in (proposed, self.status[i])]
        out = [(c, 1.0) for c in order]
        if self.m == 1:
            out.append((SLIPPING, -1.0))
        return out

    def _key(self, status, direction):
        return status.tobytes() + np.where(status == SLIPPING, direction[:, 0] > 0, False).tobytes()

    def _direction_change(self, tr):
        slipping = (self.status == SLIPPING) & (tr.status == SLIPPING)
        if not slipping.any():
            return 0.0
        return float(np.max(np.abs(tr.direction[slipping] - self.direction[slipping])))

    def _update_directions(self, tr, q):
        """3D: slip direction from the increment, cone curvature for the next step."""
        slipping = (self.status == SLIPPING) & (tr.status == SLIPPING)
        self.direction[slipping] = tr.direction[slipping]
        if self.m < 2:
            return
        norm = np.linalg.norm(q.dv, axis=1)
        scale = 1e-12 * force_scale(self.lw, self.lam) / self.problem.kappa
        ok = slipping & (norm > scale)
        self.curvature = np.zeros_like(self.curvature)
        self.curvature[ok] = self.problem.mu[ok] * np.maximum(q.P[ok], 0.0) / norm[ok]

    def _block_step(self):
        if self.coupling == "joint":
            R, b, unknown, d_known = basket_system(self.problem, self.lw, self.status,
                                                   self.direction, self.curvature, self.prev)
            return solve_partitioned(R, b, unknown, d_known)
        return self._gauss_seidel_step()

    def _gauss_seidel_step(self):
        """Literal block Gauss-Seidel: slipping basket, then open basket."""
        p, st = self.problem, self.status
        d = np.where(_known_mask(p, st), known_displacement(p, st, self.prev), self.d)
        slip, opened = np.flatnonzero(st == SLIPPING), np.flatnonzero(st == OPEN)
        R, b = slip_rows(p, self.lw, slip, self.direction[slip], self.curvature[slip],
                         self.prev[slip, :-1])
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


def _known_mask(problem, status):
    mask = np.zeros((problem.n_pairs, problem.dim), bool)
    mask[status == STUCK] = True
    mask[status == SLIPPING, -1] = True
    return mask.ravel()
