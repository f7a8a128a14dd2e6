r"""Exponential pressure-overclosure contact (Abaqus' ``EXPONENTIAL`` form)."""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .base import NormalLaw, positive

_E1 = math.e - 1.0
#: Newton steps of the inverse: from the start above the root the iterates decrease
#: monotonically and converge quadratically once within 1 of it; ``log1p(y)`` is within
#: ``log(log y)`` of the root, so 60 steps reach round-off from any y below 1e300.
NEWTON_STEPS = 60


@dataclass(frozen=True)
class ExponentialPressure(NormalLaw):
    r"""Pressure rising exponentially from a clearance ``c0``:

    .. math:: p(h) = \frac{p_0}{e - 1}\, x\,(e^{x} - 1), \qquad x = \frac{h}{c_0} + 1,

    for ``h > -c0`` and zero below: contact begins at the clearance ``c0`` (``h = -c0``)
    with zero stiffness, and the pressure at zero clearance is ``p0``.

    Parameters
    ----------
    c0 : float
        Clearance at which contact begins (m).
    p0 : float
        Pressure at zero clearance (Pa).
    """

    c0: float
    p0: float

    name = "exponential"

    def __post_init__(self):
        owner = "exponential pressure-overclosure law"
        object.__setattr__(self, "c0", positive(owner, "clearance", self.c0, "m"))
        object.__setattr__(self, "p0", positive(owner, "pressure_at_zero", self.p0, "Pa"))

    @property
    def onset(self):
        return -self.c0

    def _x(self, h):
        return np.maximum(np.asarray(h, dtype=float) / self.c0 + 1.0, 0.0)

    def pressure(self, h):
        x = self._x(h)
        return self.p0 / _E1 * x * np.expm1(x)

    def stiffness(self, h):
        x = self._x(h)
        return self.p0 / (_E1 * self.c0) * (np.expm1(x) + x * np.exp(x))

    def overclosure(self, p):
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
        return {"normal": "exponential", "clearance": self.c0, "pressure_at_zero": self.p0}
