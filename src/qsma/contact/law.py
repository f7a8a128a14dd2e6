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


def basket_transitions(status, direction, q, mu, kappa, threshold):
    """Check every pair against the inequalities of its basket (paper 16-18).

    * stuck: ``P < 0`` -> open; ``|Q| > mu P`` -> slipping in the direction
      ``-Q/|Q|``;
    * slipping: ``P < 0`` -> open; slip increment against the assumed slip
      direction, ``dv . s < 0`` (with ``mu P > 0``) -> stuck; otherwise the
      slip direction is updated to ``dv/|dv|`` (3D);
    * open: ``w < 0`` -> stuck.

    A check fails only if its violation exceeds ``threshold`` (force units;
    displacements are turned into forces with ``kappa``), so that round-off
    does not move pairs back and forth.
    """
    new, s, viol = status.copy(), direction.copy(), np.zeros(len(status))
    q_norm = np.linalg.norm(q.Q, axis=1)
    stuck, slipping, opened = status == STUCK, status == SLIPPING, status == OPEN
    tension = (stuck | slipping) & (q.P < -threshold)
    _move(new, viol, tension, OPEN, -q.P)
    overload = stuck & ~tension & (q_norm - mu * q.P > threshold)
    _move(new, viol, overload, SLIPPING, q_norm - mu * q.P)
    s[overload] = -q.Q[overload] / q_norm[overload, None]
    backward = -kappa * np.sum(q.dv * direction, axis=1)
    reversal = slipping & ~tension & (mu * q.P > 0) & (backward > threshold)
    _move(new, viol, reversal, STUCK, backward)
    closing = opened & (kappa * q.w < -threshold)
    _move(new, viol, closing, STUCK, -kappa * q.w)
    s = _updated_directions(s, new == SLIPPING, slipping, q.dv)
    return Transitions(new, s, viol)


def _move(new, viol, mask, code, measure):
    new[mask] = code
    viol[mask] = measure[mask]


def _updated_directions(s, slipping_now, slipping_before, dv):
    """Slip direction of pairs that stay slipping: the unit slip increment."""
    norm = np.linalg.norm(dv, axis=1)
    keep = slipping_now & slipping_before & (norm > 0)
    s[keep] = dv[keep] / norm[keep, None]
    return s


def slip_directions_from_forces(Q, status):
    """Slip direction ``-Q/|Q|`` of slipping pairs (zero where ``Q = 0``)."""
    norm = np.linalg.norm(Q, axis=1)
    s = np.zeros_like(Q)
    ok = (status == SLIPPING) & (norm > 0)
    s[ok] = -Q[ok] / norm[ok, None]
    return s
