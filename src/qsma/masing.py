r"""Masing hysteresis, secant frequency and damping from a modal backbone.

For a backbone ``alpha(q)`` through the origin (mass-normalised modal force equal
to ``alpha``), the Masing loop of amplitude ``(q_a, alpha_a)`` encloses

.. math:: D = 8 \int_0^{q_a} \alpha\,dq - 4 \alpha_a q_a ,

the secant frequency is :math:`\omega = \sqrt{\alpha_a / q_a}` and the equivalent
viscous damping ratio :math:`\zeta = D / (2\pi (q_a \omega)^2)`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError


@dataclass(frozen=True)
class MasingResult:
    """Per backbone point: dissipation per cycle, secant circular frequency, damping."""

    dissipation: np.ndarray
    omega: np.ndarray
    zeta: np.ndarray

    @property
    def f_hz(self):
        return self.omega / (2 * np.pi)


def masing(alpha, q) -> MasingResult:
    """Masing dissipation, secant frequency and damping ratio at each backbone point.

    The integral is the trapezoidal rule from (0, 0) through every point up to the
    current one (the benchmark's definition, docs/theory.md section 7; the analysis
    itself uses :func:`qsma.hysteresis.masing_estimate`, the same rule written on the
    deviation from the tied line, with an error estimate).
    """
    alpha = np.asarray(alpha, dtype=float)
    q = np.asarray(q, dtype=float)
    if alpha.shape != q.shape or alpha.ndim != 1:
        raise InputError(f"alpha and q must be 1-D arrays of equal length, got "
                         f"{alpha.shape} and {q.shape}")
    if not (np.all(np.isfinite(alpha)) and np.all(np.isfinite(q))):
        raise InputError("alpha and q must be finite")
    if np.any(alpha <= 0) or np.any(q <= 0):
        raise InputError("backbone points must have alpha > 0 and q > 0")
    qa = np.concatenate([[0.0], q])
    fa = np.concatenate([[0.0], alpha])
    area = np.cumsum(0.5 * (fa[1:] + fa[:-1]) * np.diff(qa))
    D = 8.0 * area - 4.0 * alpha * q
    omega = np.sqrt(alpha / q)
    zeta = D / (2 * np.pi * (q * omega) ** 2)
    return MasingResult(D, omega, zeta)


def masing_loop(alpha_b, q_b, k, n=64):
    """Points ``(q, f)`` of the Masing loop at backbone point ``k`` (unloading branch
    from ``+q_a`` to ``-q_a`` then reloading), built from the backbone by linear
    interpolation: ``f = alpha_a - 2 f_b((q_a - q)/2)`` and ``f = 2 f_b((q + q_a)/2) - alpha_a``.
    """
    qb = np.concatenate([[0.0], np.asarray(q_b, float)])
    fb = np.concatenate([[0.0], np.asarray(alpha_b, float)])
    qa, fa = qb[k + 1], fb[k + 1]
    s = np.linspace(0.0, 2 * qa, n)
    down_q, down_f = qa - s, fa - 2 * np.interp(s / 2, qb, fb)
    up_q, up_f = -qa + s, -fa + 2 * np.interp(s / 2, qb, fb)
    return np.concatenate([down_q, up_q]), np.concatenate([down_f, up_f])


def loop_area(q, f) -> float:
    """Area enclosed by a closed (or closing) polygon ``(q, f)`` (shoelace formula)."""
    q = np.asarray(q, float)
    f = np.asarray(f, float)
    return 0.5 * abs(np.dot(q, np.roll(f, -1)) - np.dot(f, np.roll(q, -1)))
