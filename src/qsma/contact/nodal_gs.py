"""``"nodal_gs"``: nodal (non-smooth) Gauss-Seidel, one pair at a time (the baseline).

A sweep visits the pairs in order. At pair ``i`` the other pairs are held,

.. math:: \\lambda_i = K_{ii} d_i + r_i, \\qquad
          r_i = \\lambda_{w,i} + \\sum_{j \\ne i} K_{ij} d_j ,

and the local problem (one pair, ``dim`` unknowns) is solved exactly: the
stuck candidate ``d_i = (d_t,prev, -g0)``, then the open candidate
``lam_i = 0``, then the slipping candidate (``d_n = -g0``,
``Q = -mu P s``; in 3D the slip direction is found by a local Newton
iteration on the cone), whichever first satisfies its inequalities. This
is the algorithm of Barber et al. that the basket method replaced. Each
sweep ends with the residual test; on an ill-conditioned K convergence
takes ~1e5 sweeps per decade (FIELD-NOTES), so the sweep count is capped
and non-convergence is reported.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .registry import Iterate, register_method
from .residual import residual

#: Default cap on sweeps (FIELD-NOTES: the baseline must cap and say so).
DEFAULT_SWEEPS = 20000
#: Local Newton iterations for the 3D slip direction.
LOCAL_ITERATIONS = 50


@register_method("nodal_gs")
def solve_nodal_gs(problem, lam_w, previous, *, tol, maxiter=None, check_every=1):
    """Nodal Gauss-Seidel sweeps with exact local solves.

    Parameters
    ----------
    maxiter : int, optional
        Sweeps over all pairs; default 20000.
    check_every : int
        Sweeps between two evaluations of the residual (stopping test).
    """
    if isinstance(check_every, bool) or not isinstance(check_every, (int, np.integer)) \
            or check_every < 1:
        raise InputError(f"check_every must be a positive integer, got {check_every!r}")
    maxiter = maxiter or DEFAULT_SWEEPS
    sweeper = _Sweeper(problem, lam_w, previous)
    r = np.inf
    for sweep in range(1, maxiter + 1):
        sweeper.sweep()
        if sweep % check_every and sweep < maxiter:
            continue
        sweeper.resync()
        r = residual(problem, lam_w, sweeper.d2, sweeper.lam2, previous)
        if r <= tol:
            return Iterate(sweeper.d2, sweeper.lam2, sweep, True,
                           f"converged in {sweep} sweeps")
    return Iterate(sweeper.d2, sweeper.lam2, maxiter, False,
                   f"no convergence in maxiter={maxiter} sweeps (residual {r:.3e})")


class _Sweeper:
    """Iterate of the nodal Gauss-Seidel and its sweep."""

    def __init__(self, problem, lam_w, previous):
        p = self.problem = problem
        self.lw = lam_w.ravel()
        self.d = previous.d.ravel().copy()
        self.lam = p.K @ self.d + self.lw
        dim = p.dim
        self.columns = [np.ascontiguousarray(p.K[:, i * dim:(i + 1) * dim])
                        for i in range(p.n_pairs)]
        self.blocks = p.diagonal_blocks
        self.t_prev = previous.d[:, :-1]
        self.local = _local_2d if dim == 2 else _local_3d
        self.args = [self._local_args(i) for i in range(p.n_pairs)]

    @property
    def d2(self):
        return self.d.reshape(-1, self.problem.dim)

    @property
    def lam2(self):
        return self.lam.reshape(-1, self.problem.dim)

    def _local_args(self, i):
        p = self.problem
        if p.dim == 2:
            (a, b), (_, c) = self.blocks[i].tolist()
            return a, b, c, float(self.t_prev[i, 0]), float(p.gap0[i]), float(p.mu[i])
        return self.blocks[i], self.t_prev[i], float(p.gap0[i]), float(p.mu[i])

    def sweep(self):
        dim, d, lam = self.problem.dim, self.d, self.lam
        for i in range(self.problem.n_pairs):
            s = slice(i * dim, (i + 1) * dim)
            old = d[s].copy()
            r = lam[s] - self.blocks[i] @ old
            new = self.local(r, *self.args[i])
            delta = new - old
            if np.any(delta):
                d[s] = new
                lam += self.columns[i] @ delta

    def resync(self):
        """Recompute ``lam`` exactly (the sweep updates it incrementally)."""
        self.lam = self.problem.K @ self.d + self.lw


def _local_2d(r, a, b, c, tp, g0, mu):
    """Exact solution of one 2D pair, ``lam = [[a, b], [b, c]] d + r``."""
    rt, rn = float(r[0]), float(r[1])
    dn = -g0
    Q, P = a * tp + b * dn + rt, b * tp + c * dn + rn
    if P >= 0.0 and abs(Q) <= mu * P:
        return np.array([tp, dn])
    det = a * c - b * b
    dt_open, dn_open = (b * rn - c * rt) / det, (b * rt - a * rn) / det
    if dn_open + g0 >= 0.0:
        return np.array([dt_open, dn_open])
    for s in (-1.0 if Q > 0 else 1.0, 1.0 if Q > 0 else -1.0):
        dt = -(rt + b * dn + mu * s * (c * dn + rn)) / (a + mu * s * b)
        if b * dt + c * dn + rn >= 0.0 and s * (dt - tp) >= 0.0:
            return np.array([dt, dn])
    return np.array([dt_open, dn_open]) if P < 0.0 else np.array([tp, dn])


def _local_3d(r, Kii, tp, g0, mu):
    """Exact solution of one 3D pair (Coulomb cone), ``lam = Kii d + r``."""
    dn = -g0
    stuck = np.array([tp[0], tp[1], dn])
    lam = Kii @ stuck + r
    P, Q = lam[2], lam[:2]
    if P >= 0.0 and np.linalg.norm(Q) <= mu * P:
        return stuck
    opened = -np.linalg.solve(Kii, r)
    if opened[2] + g0 >= 0.0:
        return opened
    v = _local_slip_3d(Kii, Q, P, mu)
    if v is not None:
        return np.array([tp[0] + v[0], tp[1] + v[1], dn])
    return opened if P < 0.0 else stuck


def _local_slip_3d(Kii, Q0, P0, mu):
    """Slip increment ``v`` with ``Q0 + A v = -mu (P0 + b.v) v/|v|``, or None.

    Newton on the slip direction, started from the stuck trial force.
    """
    A, b = Kii[:2, :2], Kii[2, :2]
    norm = np.linalg.norm(Q0)
    if norm == 0.0:
        return None
    s, C = -Q0 / norm, np.zeros((2, 2))
    for _ in range(LOCAL_ITERATIONS):
        v = np.linalg.solve(A + mu * np.outer(s, b) + C, -(Q0 + mu * P0 * s))
        size = np.linalg.norm(v)
        if size == 0.0 or P0 + b @ v < 0.0:
            return None
        s_new = v / size
        if s_new @ s <= 0.0:
            return None
        done = np.max(np.abs(s_new - s)) <= 1e-15
        s, C = s_new, mu * (P0 + b @ v) / size * (np.eye(2) - np.outer(s_new, s_new))
        if done:
            return v
    return v
