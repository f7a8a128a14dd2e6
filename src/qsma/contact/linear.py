"""Linear algebra of a fixed set of pair states: the block step of the solvers.

With every pair's state fixed, ``lam = K d + lam_w`` plus the equality of
each state is a linear system (method.md sections 3-4):

* stuck: ``d_t = d_t_prev``, ``d_n = -g0`` (``d`` known, ``lam`` follows);
* open: ``lam = 0`` (``d`` unknown);
* slipping: ``d_n = -g0`` and ``Q + mu P s + C (d_t - d_t_prev) = 0`` with
  ``s`` the slip direction and ``C = mu P0 / |dv0| (I - s s^T)`` the
  curvature of the Coulomb cone at the previous iterate (zero in 2D, where
  the equation is exact).

The unknowns are the displacement components ``U`` that the states leave
free (all of an open pair, the tangential ones of a slipping pair); the
components ``D`` are known. Writing the ``U`` equations as rows of ``d``,
``R d = b``, the block step is the small dense solve
``R[:, U] d_U = b - R[:, D] d_D``; with every pair stuck it is empty and
``lam = K d + lam_w`` is immediate.
"""
from __future__ import annotations

import numpy as np

from .state import OPEN, SLIPPING, STUCK


def known_displacement(problem, status, d_prev):
    """Displacement fixed by the states: ``(d_t_prev, -g0)`` stuck, ``d_n = -g0`` slipping.

    Components left free by the state are zero. Returns ``(N,)``.
    """
    d = np.zeros((problem.n_pairs, problem.dim))
    stuck, closed = status == STUCK, status != OPEN
    d[stuck, :-1] = d_prev[stuck, :-1]
    d[closed, -1] = -problem.gap0[closed]
    return d.ravel()


def free_components(problem, pairs_open, pairs_slipping):
    """Flat indices left free: all components of open pairs, tangential of slipping."""
    return np.concatenate([(pairs_open[:, None] * problem.dim + np.arange(problem.dim)).ravel(),
                           problem.tangent_index[pairs_slipping].ravel()])


def open_rows(problem, lam_w, pairs):
    """Rows ``lam_i = K_i d + lam_w,i = 0`` of open pairs: ``(R, b)``."""
    index = (pairs[:, None] * problem.dim + np.arange(problem.dim)).ravel()
    return problem.K[index], -lam_w[index]


def slip_rows(problem, lam_w, pairs, direction, curvature, t_prev):
    """Rows ``Q + mu P s + C (d_t - d_t_prev) = 0`` of slipping pairs: ``(R, b)``.

    Parameters
    ----------
    pairs : (k,) int
    direction : (k, m)
        Slip direction ``s`` (unit vector of the expected slip increment).
    curvature : (k,)
        ``mu P0 / |dv0|`` (0 for a fixed direction, always 0 in 2D).
    t_prev : (k, m)
        Previous converged tangential displacement.
    """
    K, m = problem.K, problem.dim - 1
    T, N = problem.tangent_index[pairs], problem.normal_index[pairs]
    ms = problem.mu[pairs, None] * direction
    rows = K[T] + ms[:, :, None] * K[N][:, None, :]
    rhs = -(lam_w[T] + ms * lam_w[N][:, None])
    if m > 1 and np.any(curvature):
        C = curvature[:, None, None] * (np.eye(m) - direction[:, :, None] * direction[:, None, :])
        k = np.arange(len(pairs))[:, None, None]
        rows[k, np.arange(m)[None, :, None], T[:, None, :]] += C
        rhs = rhs + np.einsum("kij,kj->ki", C, t_prev)
    return rows.reshape(-1, K.shape[1]), rhs.ravel()


def basket_system(problem, lam_w, status, direction, curvature, d_prev):
    """The linear system of fixed pair states: ``(R, b, U, d_known)``.

    ``lam_w`` is flat ``(N,)``; ``direction`` ``(n_pairs, m)`` and
    ``curvature`` ``(n_pairs,)`` are read at the slipping pairs.
    """
    pairs_open = np.flatnonzero(status == OPEN)
    pairs_slip = np.flatnonzero(status == SLIPPING)
    Ro, bo = open_rows(problem, lam_w, pairs_open)
    Rs, bs = slip_rows(problem, lam_w, pairs_slip, direction[pairs_slip],
                       curvature[pairs_slip], d_prev[pairs_slip, :-1])
    unknown = free_components(problem, pairs_open, pairs_slip)
    return (np.vstack([Ro, Rs]), np.concatenate([bo, bs]), unknown,
            known_displacement(problem, status, d_prev))


def solve_partitioned(rows, rhs, unknown, d_fixed):
    """Solve ``rows @ d = rhs`` for ``d[unknown]``, the other components at ``d_fixed``.

    Returns a new ``(N,)`` vector. Raises ``numpy.linalg.LinAlgError`` if the
    block is singular.
    """
    d = np.array(d_fixed, dtype=float)
    if unknown.size == 0:
        return d
    d[unknown] = 0.0
    d[unknown] = np.linalg.solve(rows[:, unknown], rhs - rows @ d)
    return d
