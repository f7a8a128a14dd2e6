"""Hard normal contact: no pressure while open, no overclosure while pressed."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import NormalLaw


@dataclass(frozen=True)
class Hard(NormalLaw):
    """Rigid normal contact (Signorini): ``w >= 0``, ``p >= 0``, ``p w = 0``."""

    name = "hard"
    hard = True
    linear = True

    def pressure(self, h):
        raise TypeError("hard contact has no pressure-overclosure function")

    stiffness = pressure

    def overclosure(self, p):
        return np.zeros_like(np.asarray(p, dtype=float))

    def tangent_at_pressure(self, p):
        return np.full_like(np.asarray(p, dtype=float), np.inf)

    def scale_pressure(self):
        return 0.0

    def as_dict(self):
        return {"normal": "hard"}
