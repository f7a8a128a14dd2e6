"""Linear algebra of a fixed set of pair states: the block step of the solvers.

With every pair's state fixed, ``lam = K d + lam_w`` plus the equality of
each state is a linear system (method.md sections 3-4):

* stuck: ``d_t = d_t_prev``, ``d_n = -g0`` (``d`` known, ``lam`` follows);
* open: ``lam = 0`` (``d`` unknown);
* slipping: ``d_n = -g0`` and ``Q + mu P s = 0`` with ``s`` the slip
  direction; in 3D linearised in the direction (:func:`slip_rows`), exact
  in 2D.

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


def slip_rows(problem, lam_w, pairs, direction, alpha, t_prev, c):
    r"""Rows of the slip law of slipping pairs: ``(R, b)`` with ``R d = b``.

    The slip law ``Q = -mu P s`` with the slip direction ``s`` taken from the
    augmented shear, ``s = -sigma_t/|sigma_t|``, ``sigma_t = Q - c dv``,
    linearised at the current iterate (a Newton step on the direction):

    .. math:: (I - \alpha \Pi) (Q - c\,dv) + c\,dv + \mu P s = 0 ,
              \qquad \Pi = I - s s^T, \quad
              \alpha = \mu \sigma_n / |\sigma_t| ,

    i.e. ``(I - alpha Pi) K_t d + mu s K_n d + alpha c Pi d_t =
    -(I - alpha Pi) lam_w,t - mu s lam_w,n + alpha c Pi d_t,prev``. With
    ``alpha = 0`` (always in 2D, where ``Pi = 0``, and for a direction held
    fixed) it is ``Q + mu P s = 0``.

    Parameters
    ----------
    pairs : (k,) int
    direction : (k, m)
        Slip direction ``s`` (unit vector of the expected slip increment).
    alpha : (k,)
        ``mu sigma_n / |sigma_t|`` in ``[0, 1]`` at the current iterate.
    t_prev : (k, m)
        Previous converged tangential displacement.
    c : float
        Augmentation of ``sigma_t``.
    """
    K, m = problem.K, problem.dim - 1
    T, N = problem.tangent_index[pairs], problem.normal_index[pairs]
    ms = problem.mu[pairs, None] * direction
    if m == 1:                                   # 2D: plain rows Q + mu s P = 0
        return (K[T[:, 0]] + ms * K[N],
                -(lam_w[T[:, 0]] + ms[:, 0] * lam_w[N]))
    rows = K[T] + ms[:, :, None] * K[N][:, None, :]
    rhs = -(lam_w[T] + ms * lam_w[N][:, None])
    if m > 1 and np.any(alpha):
        Pi = alpha[:, None, None] * (np.eye(m) - direction[:, :, None] * direction[:, None, :])
        rows -= np.einsum("kij,kjc->kic", Pi, K[T])
        rhs += np.einsum("kij,kj->ki", Pi, lam_w[T] + c * t_prev)
        k = np.arange(len(pairs))[:, None, None]
        rows[k, np.arange(m)[None, :, None], T[:, None, :]] += c * Pi
    return rows.reshape(-1, K.shape[1]), rhs.ravel()


def basket_system(problem, lam_w, status, direction, alpha, d_prev, c):
    """The linear system of fixed pair states: ``(R, b, U, d_known)``.

    ``lam_w`` is flat ``(N,)``; ``direction`` ``(n_pairs, m)`` and ``alpha``
    ``(n_pairs,)`` are read at the slipping pairs (see :func:`slip_rows`).
    """
    pairs_open = np.flatnonzero(status == OPEN)
    pairs_slip = np.flatnonzero(status == SLIPPING)
    Ro, bo = open_rows(problem, lam_w, pairs_open)
    Rs, bs = slip_rows(problem, lam_w, pairs_slip, direction[pairs_slip], alpha[pairs_slip],
                       d_prev[pairs_slip, :-1], c)
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
