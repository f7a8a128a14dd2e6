r"""Exponential pressure-overclosure contact (Abaqus' ``EXPONENTIAL`` form)."""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ...errors import InputError
from .base import NormalLaw, positive

_E1 = math.e - 1.0
#: Newton steps of the inverse: from the start above the root the iterates decrease
#: monotonically and converge quadratically once within 1 of it; ``log1p(y)`` is within
#: ``log(log y)`` of the root, so 60 steps reach round-off from any y below 1e300.
NEWTON_STEPS = 60


#: The forms of the exponential law: Abaqus' (zero pressure and slope at the clearance
#: ``c0``) and CalculiX's (a pure exponential, 1 % of ``p0`` at ``c0``, cut there).
FORMS = ("abaqus", "calculix")


@dataclass(frozen=True)
class ExponentialPressure(NormalLaw):
    r"""Pressure rising exponentially from a clearance ``c0``.

    ``form="abaqus"`` (Abaqus' ``EXPONENTIAL``):

    .. math:: p(h) = \frac{p_0}{e - 1}\, x\,(e^{x} - 1), \qquad x = \frac{h}{c_0} + 1,

    for ``h > -c0`` and zero below: contact begins at the clearance ``c0`` (``h = -c0``)
    with zero stiffness, and the pressure at zero clearance is ``p0``.

    ``form="calculix"`` (CalculiX's ``EXPONENTIAL``): ``p = p0 exp(beta h)`` with
    ``beta = ln(100) / c0`` for ``h > -c0`` (1 % of ``p0`` at the clearance ``c0``) and
    zero beyond: the pressure jumps from 0 to ``p0 / 100`` at ``h = -c0``, a point there
    carries any pressure up to it (a vertical segment of the law, rigid).

    Parameters
    ----------
    c0 : float
        Clearance at which contact begins (m).
    p0 : float
        Pressure at zero clearance (Pa).
    form : {"abaqus", "calculix"}
    """

    c0: float
    p0: float
    form: str = "abaqus"

    name = "exponential"

    def __post_init__(self):
        owner = "exponential pressure-overclosure law"
        object.__setattr__(self, "c0", positive(owner, "clearance", self.c0, "m"))
        object.__setattr__(self, "p0", positive(owner, "pressure_at_zero", self.p0, "Pa"))
        if self.form not in FORMS:
            raise InputError(f"{owner}: form must be one of {FORMS}, got {self.form!r}")

    @property
    def onset(self):
        return -self.c0

    @property
    def _beta(self):
        return math.log(100.0) / self.c0

    def _x(self, h):
        return np.maximum(np.asarray(h, dtype=float) / self.c0 + 1.0, 0.0)

    def pressure(self, h):
        if self.form == "calculix":
            h = np.asarray(h, dtype=float)
            return np.where(h > -self.c0, self.p0 * np.exp(self._beta * np.maximum(
                h, -self.c0)), 0.0)
        x = self._x(h)
        return self.p0 / _E1 * x * np.expm1(x)

    def stiffness(self, h):
        if self.form == "calculix":
            return self._beta * self.pressure(h)
        x = self._x(h)
        return self.p0 / (_E1 * self.c0) * (np.expm1(x) + x * np.exp(x))

    def tangent_at_pressure(self, p):
        if self.form == "calculix":
            # on the vertical segment the slope just above the jump: a layer linearised
            # there is a chord (its shift makes it exact), and a finite one
            return self._beta * np.maximum(np.asarray(p, dtype=float), self.p0 / 100.0)
        return self.stiffness(self.overclosure(np.maximum(p, 0.0)))

    def overclosure(self, p):
        if self.form == "calculix":               # -c0 exactly on the vertical segment
            p = np.asarray(p, dtype=float)
            above = p > self.p0 / 100.0
            return np.where(above, np.log(np.where(above, p, self.p0) / self.p0)
                            / self._beta, -self.c0)
        return self._abaqus_overclosure(p)

    def _abaqus_overclosure(self, p):
        r"""Inverse of :meth:`pressure`: ``x (e^x - 1) = y`` with ``y = (e - 1) p / p0``
        solved by Newton's method from above (the function is convex and increasing for
        ``x >= 0``, so the iterates decrease monotonically to the root)."""
        y = np.maximum(np.asarray(p, dtype=float), 0.0) * _E1 / self.p0
        x = np.where(y < _E1, np.sqrt(y), np.log1p(y))          # f(x) >= 0 there
        for _ in range(NEWTON_STEPS):
            ex = np.exp(x)
            f = x * (ex - 1.0) - y
            df = ex - 1.0 + x * ex
            step = np.where(df > 0, f / np.where(df > 0, df, 1.0), 0.0)
            x = np.maximum(x - step, 0.0)
            if np.abs(step).max(initial=0.0) <= 1e-15 * (1.0 + x.max(initial=0.0)):
                break
        return self.c0 * (x - 1.0)

    def scale_pressure(self):
        return self.p0

    def as_dict(self):
        return {"normal": "exponential", "clearance": self.c0, "pressure_at_zero": self.p0,
                "form": self.form}
