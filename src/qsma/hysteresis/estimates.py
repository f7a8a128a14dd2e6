r"""Error estimates of a computed loop: the quadrature of its area (Richardson, the
same rule on every second point, ``|I_h - I_2h| / 3`` for a rule of order two), the
path error of its increments from the change between refinement rounds, and the
intervals whose share of the loop has settled.
"""
from __future__ import annotations

import numpy as np

from .loop import cycle_area


def _coarse(n_branch):
    """Indices of a cycle path of two branches of ``n_branch`` points each that keep
    every second point counted back from each turning point."""
    branch = np.arange(1, n_branch + 1)
    keep = branch[(n_branch - branch) % 2 == 0]
    return np.concatenate([[0], keep, n_branch + keep])


def cycle_area_error(alpha, q, k_ref) -> float:
    """Estimate ``|D_h - D_2h| / 3`` of the trapezoidal error of :func:`cycle_area`."""
    n_branch = (len(alpha) - 1) // 2
    if n_branch < 2:
        return 0.0
    idx = _coarse(n_branch)
    fine = cycle_area(alpha, q, k_ref)
    coarse = cycle_area(np.asarray(alpha)[idx], np.asarray(q)[idx], k_ref)
    return abs(fine - coarse) / 3.0


def _parents(u, coarse):
    """Per branch interval of ``u`` (ending at ``u[i]``), the interval of ``coarse`` (a
    subset of ``u`` with the same last point) that holds it."""
    return np.searchsorted(coarse, u, side="left")


def _interval_pieces(alpha, q, k_ref):
    """Per branch interval, the trapezoids of :func:`cycle_area` and the increments of
    ``q``, each as ``(n, 2)``: the unloading branch, then the reloading one."""
    alpha, q = np.asarray(alpha, float), np.asarray(q, float)
    r = q - alpha / k_ref
    area = 0.5 * (alpha[1:] + alpha[:-1]) * np.diff(r)
    dq = np.diff(q)
    n = len(area) // 2
    return np.stack([area[:n], area[n:]], axis=1), np.stack([dq[:n], dq[n:]], axis=1)


def _settled_intervals(fine, coarse_loop, u, coarse, k_ref, budget):
    r"""The branch intervals of ``u`` whose coarse interval's share of the cycle hardly
    changed when its increments were halved: ``(settled (len(u),) bool, bound)``.

    Per interval ``j`` of ``coarse``, the change of its trapezoids of ``D`` over both
    branches, ``\Delta D_j``, and of its increments of ``q``, ``\Delta q_j``, from the
    cycle on ``coarse`` (``coarse_loop``) to the one on ``u`` (``fine``). The intervals
    of the smallest ``\Delta D_j`` are settled as long as their sum stays within
    ``budget`` and that of their ``\Delta q_j`` within ``budget / |D|`` times the range
    of ``q``: halving one again would change the loop by about its ``\Delta_j`` or
    less (a first-order path error halves with the increment), so ``bound``, the sum
    of their ``\Delta D_j``, is what their path error may still be, added to the
    loop's error estimate from the next round on (this round's change of ``D``, the
    estimate of the path error of all the intervals, holds their changes). A history
    shifted by the intervals before moves ``q`` along a branch, not the area or the
    increments of an interval, so ``\Delta_j`` is the interval's own."""
    n = len(coarse)
    parent = _parents(u, coarse)
    area_f, dq_f = _interval_pieces(fine.alpha, fine.q, k_ref)
    area_c, dq_c = _interval_pieces(coarse_loop.alpha, coarse_loop.q, k_ref)
    per = lambda x: np.stack([np.bincount(parent, x[:, b], minlength=n) for b in (0, 1)], 1)
    dD = np.abs(per(area_f) - area_c).sum(axis=1)
    dq = np.abs(per(dq_f) - dq_c).sum(axis=1)
    span = max(np.ptp(fine.q), np.finfo(float).tiny)
    q_budget = budget / max(abs(fine.dissipation), np.finfo(float).tiny) * span
    order = np.argsort(dD, kind="stable")            # the smallest changes first
    fits = (np.cumsum(dD[order]) <= budget) & (np.cumsum(dq[order]) <= q_budget)
    still = np.zeros(n, bool)
    still[order[:np.argmin(fits) if not fits.all() else n]] = True
    return still[parent], float(dD[still].sum())


def _path_error(change, last_change, settled=0.0):
    """What is left of the path error after a round whose settled cycle changed ``D``
    by ``change``, the round before by ``last_change`` (None: the first round). Halving
    the increments halves the error of a first-order path, so the last change bounds
    what is left when the changes shrink by half or faster; a slower ratio ``rho``
    leaves ``rho / (1 - rho)`` times the last change (a geometric series); changes
    that did not shrink say only that the error is at least the larger one.
    ``settled``: the last changes of the intervals no longer halved
    (:func:`_settled_intervals`), counted with the same factor."""
    if last_change is None or last_change <= 0.0:
        return change + settled
    rho = change / last_change
    if rho >= 1.0:
        return max(change, last_change) + settled
    return (change + settled) * max(1.0, rho / (1.0 - rho))


def _shape_change(q, q_previous):
    """Largest change of ``q`` about its mean between two cycles on the same points,
    relative to the range of ``q``."""
    if len(q) != len(q_previous) or len(q) == 0:
        return np.inf
    diff = np.abs((q - q.mean()) - (q_previous - q_previous.mean())).max()
    return float(diff / max(np.ptp(q), np.finfo(float).tiny))
