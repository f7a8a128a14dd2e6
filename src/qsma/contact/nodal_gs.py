"""``"nodal_gs"``: nodal (non-smooth) Gauss-Seidel, one pair at a time (the baseline).

A sweep visits the pairs in order. At pair ``i`` the other pairs are held,

.. math:: \\lambda_i = K_{ii} d_i + r_i, \\qquad
          r_i = \\lambda_{w,i} + \\sum_{j \\ne i} K_{ij} d_j ,

and the local problem (one pair, ``dim`` unknowns) is solved exactly by
:func:`qsma.contact.local.pair_solution` (every stuck, open and slipping
candidate, the slip direction in 3D from the exact roots of a quartic; the
first valid one in that order). This is the algorithm of Barber et al. that
the basket method replaced. Each sweep ends with the residual test; on an
ill-conditioned K convergence takes ~1e5 sweeps per decade of residual
(measured on sandwich-2d, cond 2e6), so the sweep count is capped and
non-convergence is reported.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .local import pair_solution, pair_solution_2d
from .registry import Iterate, register_method
from .residual import residual

#: Default cap on sweeps (the baseline stalls on ill-conditioned K: it must cap
#: and say so).
DEFAULT_SWEEPS = 20000


@register_method("nodal_gs")
def solve_nodal_gs(problem, lam_w, previous, *, tol, maxiter=None, guess=None, check_every=1):
    """Nodal Gauss-Seidel sweeps with exact local solves.

    Parameters
    ----------
    maxiter : int, optional
        Sweeps over all pairs; default 20000.
    check_every : int
        Sweeps between two evaluations of the residual (stopping test).
    guess : ContactState, optional
        Starting displacement (default ``previous``).
    """
    if isinstance(check_every, bool) or not isinstance(check_every, (int, np.integer)) \
            or check_every < 1:
        raise InputError(f"check_every must be a positive integer, got {check_every!r}")
    maxiter = maxiter or DEFAULT_SWEEPS
    sweeper = _Sweeper(problem, lam_w, previous, previous if guess is None else guess)
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

    def __init__(self, problem, lam_w, previous, guess):
        p = self.problem = problem
        self.lw = lam_w.ravel()
        self.d = np.array(guess.d, dtype=float).ravel()
        self.lam = p.K @ self.d + self.lw
        dim = p.dim
        self.columns = [np.ascontiguousarray(p.K[:, i * dim:(i + 1) * dim])
                        for i in range(p.n_pairs)]
        self.blocks = p.diagonal_blocks
        self.t_prev = previous.d[:, :-1]
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

    def _local(self, i, r):
        """Exact solution of pair ``i`` with the others held, ``lam_i = K_ii d_i + r``."""
        args = self.args[i]
        if self.problem.dim == 2:
            a, b, c, tp, g0, mu = args
            return np.array(pair_solution_2d(a, b, c, float(r[0]), float(r[1]), tp, g0, mu))
        return pair_solution(args[0], r, *args[1:]).d

    def sweep(self):
        dim, d, lam = self.problem.dim, self.d, self.lam
        for i in range(self.problem.n_pairs):
            s = slice(i * dim, (i + 1) * dim)
            old = d[s].copy()
            r = lam[s] - self.blocks[i] @ old
            new = self._local(i, r)
            delta = new - old
            if np.any(delta):
                d[s] = new
                lam += self.columns[i] @ delta

    def resync(self):
        """Recompute ``lam`` exactly (the sweep updates it incrementally)."""
        self.lam = self.problem.K @ self.d + self.lw

