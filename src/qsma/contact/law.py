"""Coulomb contact law of one node pair, vectorised over pairs (method.md section 4).

Every per-pair rule of the package lives here: the kinematics (opening,
slip increment), the projection onto the friction disk, the natural-map
residual, the classification into stuck / slipping / open, and the state
checks of the basket method. The tangential part is always a vector of
``dim - 1`` components, so 2D and 3D (Coulomb cone) share one code path.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .state import OPEN, SLIPPING, STUCK


class PairQuantities(NamedTuple):
    """Forces and kinematics of every pair.

    ``P`` (n,) pressure, ``Q`` (n, m) shear, ``w`` (n,) opening ``d_n + g0``,
    ``dv`` (n, m) slip increment ``d_t - d_t_prev``, with ``m = dim - 1``.
    """

    P: np.ndarray
    Q: np.ndarray
    w: np.ndarray
    dv: np.ndarray


def pair_quantities(problem, d, lam, d_prev):
    """Split ``(d, lam)`` of shape ``(n_pairs, dim)`` into :class:`PairQuantities`."""
    return PairQuantities(lam[:, -1], lam[:, :-1], d[:, -1] + problem.gap0,
                          d[:, :-1] - d_prev[:, :-1])


def project_disk(x, radius):
    """Euclidean projection of each row of ``x`` onto the disk of radius ``radius``.

    .. math:: \\mathrm{proj}_r(x) = x \\min(1, r / \\lVert x \\rVert)

    Parameters
    ----------
    x : (n, m)
        Tangential vectors (``m = 1`` in 2D: the disk is ``[-r, r]``).
    radius : (n,)
        Non-negative radii.
    """
    norm = np.linalg.norm(x, axis=1)
    scale = np.minimum(1.0, radius / np.maximum(norm, np.finfo(float).tiny))
    return x * scale[:, None]


def natural_map(q, mu, c):
    """Absolute natural-map residuals of every pair.

    .. math::
        r_n = |P - \\max(0, P - c w)|, \\qquad
        r_t = \\lVert Q - \\mathrm{proj}_{\\mu \\max(P, 0)}(Q - c\\, dv) \\rVert

    Both vanish exactly when the pair satisfies one of the rows of the table
    of method.md section 4 (open, stuck or slipping).
    """
    r_n = np.abs(q.P - np.maximum(0.0, q.P - c * q.w))
    radius = mu * np.maximum(q.P, 0.0)
    r_t = np.linalg.norm(q.Q - project_disk(q.Q - c * q.dv, radius), axis=1)
    return r_n, r_t


class AugmentedForces(NamedTuple):
    """Alart-Curnier augmented forces and the sets they define.

    ``sigma_n = P - c w``, ``sigma_t = Q - c dv``; a pair is closed where
    ``sigma_n > 0`` and stuck where also ``|sigma_t| <= mu sigma_n``.
    """

    sigma_n: np.ndarray
    sigma_t: np.ndarray
    closed: np.ndarray
    stick: np.ndarray


def augmented_forces(q, mu, c):
    """Alart-Curnier augmented forces of every pair (see :class:`AugmentedForces`)."""
    sigma_n = q.P - c * q.w
    sigma_t = q.Q - c * q.dv
    closed = sigma_n > 0
    stick = closed & (np.linalg.norm(sigma_t, axis=1) <= mu * sigma_n)
    return AugmentedForces(sigma_n, sigma_t, closed, stick)


def classify(q, mu, c):
    """Status of every pair from its forces and kinematics.

    Open where ``P - c w <= 0``; otherwise stuck where
    ``|Q - c dv| <= mu (P - c w)`` and slipping elsewhere (the Alart-Curnier
    sets with ``c`` the stiffness scale). At a solution this is the row of
    the table of method.md section 4 that the pair satisfies; a pair on the
    border of two rows (zero pressure and zero opening, or ``|Q| = mu P`` with
    zero slip) satisfies both and is reported in the first of open, stuck.
    """
    a = augmented_forces(q, mu, c)
    return np.where(~a.closed, OPEN, np.where(a.stick, STUCK, SLIPPING))


class Transitions(NamedTuple):
    """Result of the basket state checks.

    ``status`` (n,) proposed status, ``direction`` (n, m) proposed slip
    direction (unit vector of the slip increment for slipping pairs),
    ``violation`` (n,) size of the violated inequality in force units (0
    where the check passed).
    """

    status: np.ndarray
    direction: np.ndarray
    violation: np.ndarray


def basket_transitions(status, direction, q, mu, kappa, threshold, local):
    """Check every pair against the inequalities of its basket (paper 16-18).

    Failed checks:

    * stuck: ``P < 0`` or ``|Q| > mu P``;
    * slipping: ``P < 0``, or a slip increment against the assumed slip
      direction, ``dv . s < 0`` (with ``mu P > 0``);
    * open: ``w < 0``.

    A pair that fails moves to the paper's default basket (stuck -> open if
    ``P < 0`` else slipping along ``-Q/|Q|``; slipping -> open if ``P < 0``
    else stuck; open -> stuck) if its exact one-pair solution with the other
    pairs held (``local``, :func:`local_states`) allows that state; otherwise
    to the first other state the one-pair solution allows (stuck, slipping,
    open), or to the default if none does. Pairs that stay slipping take the direction
    of their slip increment (3D). A check fails only if its violation exceeds
    ``threshold`` (force units; displacements are turned into forces with
    ``kappa``), so that round-off does not move pairs back and forth.

    Parameters
    ----------
    local : LocalStates
        One-pair solutions at the current iterate.
    """
    q_norm = np.linalg.norm(q.Q, axis=1)
    stuck, slipping, opened = status == STUCK, status == SLIPPING, status == OPEN
    tension = np.where(stuck | slipping, -q.P, 0.0)
    overload = np.where(stuck, q_norm - mu * q.P, 0.0)
    backward = np.where(slipping & (mu * q.P > 0), -kappa * np.sum(q.dv * direction, axis=1), 0.0)
    closing = np.where(opened, -kappa * q.w, 0.0)
    viol = np.max([tension, overload, backward, closing], axis=0)
    failed = viol > threshold
    default = np.where(opened | (tension > threshold), OPEN, np.where(stuck, SLIPPING, STUCK))
    new = np.where(failed, _target(status, default, local.valid), status)
    s = direction.copy()
    fresh = failed & (new == SLIPPING)
    s[fresh] = local.direction[fresh]
    s = _updated_directions(s, new == SLIPPING, slipping & ~failed, q.Q - kappa * q.dv)
    return Transitions(new, s, np.where(failed, viol, 0.0))


def _target(status, default, valid):
    """Default basket if locally valid, else the first valid other basket."""
    rows = np.arange(len(status))
    allowed = valid.copy()
    allowed[rows, status] = False
    first = np.where(allowed.any(axis=1), np.argmax(allowed, axis=1), default)
    return np.where(valid[rows, default], default, first)


class LocalStates(NamedTuple):
    """Exact one-pair solutions of every pair (the other pairs held).

    ``valid`` (n, 3) bool: whether the stuck, slipping and open candidates
    (columns in the order of the status codes) satisfy their inequalities;
    ``direction`` (n, m) the slip direction of the slipping candidate.
    """

    valid: np.ndarray
    direction: np.ndarray


def local_states(problem, d, lam, d_prev, threshold):
    """Which rows of the contact law each pair can satisfy when solved alone.

    With the other pairs held, pair ``i`` sees ``lam_i = K_ii d_i + r_i``,
    ``r_i = lam_i - K_ii d_i``. Its candidates: stuck
    (``d_i = (d_t,prev, -g0)``: needs ``P >= 0``, ``|Q| <= mu P``); open
    (``lam_i = 0``: needs ``w >= 0``); slipping (``d_n = -g0``,
    ``Q = -mu P s`` with ``s = -Q/|Q|`` of the stuck trial force, held fixed;
    in 2D the other sign is tried too: needs ``P >= 0``, ``dv . s >= 0``).

    Parameters
    ----------
    d, lam, d_prev : (n_pairs, dim)
    threshold : float
        Tolerance of the inequalities, force units.
    """
    Kii, mu, kappa = problem.diagonal_blocks, problem.mu, problem.kappa
    r = lam - np.einsum("kij,kj->ki", Kii, d)
    d_stuck = np.concatenate([d_prev[:, :-1], -problem.gap0[:, None]], axis=1)
    lam_stuck = np.einsum("kij,kj->ki", Kii, d_stuck) + r
    P, Q = lam_stuck[:, -1], lam_stuck[:, :-1]
    q_norm = np.linalg.norm(Q, axis=1)
    stuck_ok = (P >= -threshold) & (q_norm - mu * P <= threshold)
    w_open = -np.linalg.solve(Kii, r[:, :, None])[:, -1, 0] + problem.gap0
    open_ok = kappa * w_open >= -threshold
    s = -Q / np.maximum(q_norm, np.finfo(float).tiny)[:, None]
    s[q_norm == 0, 0] = 1.0
    slip_ok = _slip_consistent(Kii, Q, P, s, mu, kappa, threshold)
    if problem.dim == 2:
        flip = ~slip_ok & _slip_consistent(Kii, Q, P, -s, mu, kappa, threshold)
        s[flip], slip_ok = -s[flip], slip_ok | flip
    return LocalStates(np.stack([stuck_ok, slip_ok, open_ok], axis=1), s)


def _slip_consistent(Kii, Q0, P0, s, mu, kappa, threshold):
    """Whether slipping along ``s`` is consistent for each pair alone.

    The slip increment ``v`` solves ``(A + mu s b^T) v = -(Q0 + mu P0 s)``
    (``A = K_tt``, ``b = K_nt`` of the pair, ``Q0, P0`` the stuck trial
    forces); consistent if ``P0 + b.v >= 0`` and ``v . s >= 0``.
    """
    A, b = Kii[:, :-1, :-1], Kii[:, -1, :-1]
    M = A + mu[:, None, None] * s[:, :, None] * b[:, None, :]
    rhs = -(Q0 + (mu * P0)[:, None] * s)
    singular = np.abs(np.linalg.det(M)) <= 1e-14 * np.abs(np.linalg.det(A))
    M[singular] = A[singular]
    v = np.linalg.solve(M, rhs[:, :, None])[:, :, 0]
    P = P0 + np.sum(b * v, axis=1)
    return ~singular & (P >= -threshold) & (kappa * np.sum(v * s, axis=1) >= -threshold)


def _updated_directions(s, slipping_now, slipping_before, sigma_t):
    """Slip direction of pairs that stay slipping: ``-sigma_t/|sigma_t|``.

    ``sigma_t = Q - kappa dv`` is the augmented shear; its projection on the
    friction disk is the next shear, so the slip direction is opposite to it
    (at a solution, ``sigma_t = -(mu P + kappa |dv|) s``).
    """
    norm = np.linalg.norm(sigma_t, axis=1)
    keep = slipping_now & slipping_before & (norm > 0)
    s[keep] = -sigma_t[keep] / norm[keep, None]
    return s


def slip_directions_from_forces(Q, status):
    """Slip direction ``-Q/|Q|`` of slipping pairs (zero where ``Q = 0``)."""
    norm = np.linalg.norm(Q, axis=1)
    s = np.zeros_like(Q)
    ok = (status == SLIPPING) & (norm > 0)
    s[ok] = -Q[ok] / norm[ok, None]
    return s
