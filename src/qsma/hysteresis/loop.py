r"""One cycle of the modal coordinate as data: :class:`Loop`, the path of a cycle and
the area it encloses.

Every area is computed by the trapezoidal rule on the deviation from a linear
reference ``k_ref`` (``r = q - alpha/k_ref``): the result is the same number in exact
arithmetic (the trapezoidal rule integrates the linear part exactly and its
closed-path integral vanishes), but the round-off of two large, nearly equal areas is
avoided, so a joint that stays stuck gets ``D = 0`` to round-off of the *nonlinear*
part.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The ways a loop computation ends (:attr:`Loop.outcome`).
LOOP_OUTCOMES = ("stabilised", "not_stabilised", "solve_failed")


@dataclass(frozen=True, eq=False)
class Loop:
    """The stabilised quasi-static hysteresis loop at modal-force amplitude ``A``.

    Attributes
    ----------
    amplitude : float
        ``A``, the modal force at the turning points ``+A`` and ``-A``.
    alpha, q : (n,) arrays
        The stabilised cycle: from ``+A`` down to ``-A`` and back to ``+A``.
    dissipation : float
        ``D = \\oint alpha dq`` of the stabilised cycle (NaN if the loop failed).
    first_dissipation : float
        ``D`` of the first cycle after the monotonic ramp, on the initial increments
        (differs on shakedown).
    error : float
        Estimate of the integration error of ``dissipation`` (absolute).
    q_top, q_bottom : float
        ``q`` at ``+A`` and ``-A`` of the stabilised cycle.
    n_cycles : int
        Cycles on the initial increments until they settled (the refinement rounds'
        are :attr:`refinement_cycles`).
    n_solves : int
        Contact solves spent (all refinement rounds included).
    coarse_dissipation : float
        ``D`` of the cycle that repeated on the initial increments (NaN when
        ``refine_rounds = 0`` or when no cycle repeated): the reference of
        :attr:`shakedown`, on the same increments as ``first_dissipation``.
    refinement_cycles : int
        Cycles solved on refined increments (one or more per refinement round, until
        they settle).
    seconds : float
        Wall-clock seconds the loop took in the process that computed it (NaN where
        not measured).
    outcome : str
        One of :data:`LOOP_OUTCOMES`: ``"stabilised"`` (the answer), ``"not_stabilised"``
        (no cycle repeated within ``max_cycles``), ``"solve_failed"`` (a contact solve
        of the history failed; no dissipation).
    message : str
    """

    amplitude: float
    alpha: np.ndarray
    q: np.ndarray
    dissipation: float
    first_dissipation: float
    error: float
    q_top: float
    q_bottom: float
    n_cycles: int
    n_solves: int
    outcome: str
    message: str
    coarse_dissipation: float = float("nan")
    refinement_cycles: int = 0
    seconds: float = float("nan")

    @property
    def success(self) -> bool:
        """Only a stabilised loop is an answer."""
        return self.outcome == "stabilised"

    @property
    def stabilised(self) -> bool:
        return self.outcome == "stabilised"

    @property
    def q_amplitude(self) -> float:
        """Half the peak-to-peak modal amplitude, ``(q_top - q_bottom) / 2``."""
        return 0.5 * (self.q_top - self.q_bottom)

    @property
    def omega(self) -> float:
        """Secant circular frequency of the peak-to-peak line, ``sqrt(2A / (q_top - q_bottom))``."""
        return float(np.sqrt(self.amplitude / self.q_amplitude))

    @property
    def zeta(self) -> float:
        """Equivalent damping ratio ``D / (2 pi A q_a)`` (= ``D / (2 pi (q_a w)^2)``)."""
        return float(self.dissipation / (2 * np.pi * self.amplitude * self.q_amplitude))

    @property
    def shakedown(self) -> bool:
        """Whether the first cycle dissipated differently from the stabilised one (both
        on the initial increments)."""
        stabilised = (self.dissipation if np.isnan(self.coarse_dissipation)
                      else self.coarse_dissipation)
        return bool(self.n_cycles > 1 and not np.isclose(
            self.first_dissipation, stabilised, rtol=1e-6,
            atol=1e-9 * self.amplitude * abs(self.q_amplitude)))


def cycle_path(amplitude, fractions) -> np.ndarray:
    """Modal forces of one cycle: ``+A``, then ``A - 2A u`` and ``-A + 2A u`` for the
    increasing ``fractions`` ``u`` (the last is 1)."""
    u = np.asarray(fractions, dtype=float)
    return np.concatenate([[amplitude], amplitude * (1 - 2 * u), amplitude * (2 * u - 1)])


def cycle_area(alpha, q, k_ref) -> float:
    """``\\oint alpha dq`` of a path from ``+A`` to ``+A`` by the trapezoidal rule, on the
    deviation ``r = q - alpha / k_ref`` (the same value, without the cancellation)."""
    alpha = np.asarray(alpha, dtype=float)
    r = np.asarray(q, dtype=float) - alpha / k_ref
    return float(np.sum(0.5 * (alpha[1:] + alpha[:-1]) * np.diff(r)))


def _failed(A, path, qs, first, cycle, n_solves, message):
    nan = float("nan")
    q = np.array(qs, dtype=float)
    return Loop(A, np.asarray(path, float), q, nan, nan if first is None else first, nan,
                q[0], nan, cycle, n_solves, "solve_failed", message)
