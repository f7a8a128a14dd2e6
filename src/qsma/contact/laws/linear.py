"""Linear pressure-overclosure (penalty) contact: ``p = k max(h, 0)``."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import NormalLaw, positive


@dataclass(frozen=True)
class LinearPressure(NormalLaw):
    """``p = k h`` for overclosure ``h > 0``, zero while open.

    The layer of Abaqus and CalculiX ``*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR``
    (without the tension a node-to-surface contact of CalculiX allows at small
    clearances).

    Parameters
    ----------
    stiffness : float
        ``k``, pressure per overclosure (Pa/m, N/m^3).
    """

    k: float

    name = "linear"
    linear = True

    def __post_init__(self):
        object.__setattr__(self, "k", positive("linear pressure-overclosure law",
                                               "stiffness", self.k, "Pa/m (N/m^3)"))

    def pressure(self, h):
        return self.k * np.maximum(np.asarray(h, dtype=float), 0.0)

    def stiffness(self, h):
        return np.where(np.asarray(h, dtype=float) > 0, self.k, 0.0)

    def overclosure(self, p):
        return np.maximum(np.asarray(p, dtype=float), 0.0) / self.k

    def tangent_at_pressure(self, p):
        return np.full_like(np.asarray(p, dtype=float), self.k)

    def scale_pressure(self):
        return 0.0

    def as_dict(self):
        return {"normal": "linear", "normal_stiffness": self.k}
