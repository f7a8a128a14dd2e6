"""Tangential part of the layer: rigid stick, or an elastic stick of given stiffness."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import TangentialLaw, positive


@dataclass(frozen=True)
class RigidStick(TangentialLaw):
    """No tangential displacement while the pair sticks."""

    name = "rigid"
    rigid = True

    def stiffness(self, p):
        return np.full_like(np.asarray(p, dtype=float), np.inf)

    def as_dict(self):
        return {"tangential": "rigid"}


@dataclass(frozen=True)
class ElasticStick(TangentialLaw):
    """A stick stiffness ``k_t`` per unit area (Pa/m): while the pair sticks the shear
    grows by ``k_t`` times the tangential displacement; at ``|q| = mu p`` it slips.

    The *stick slope* of CalculiX's ``*FRICTION`` (its second value) is this ``k_t``.
    """

    k: float

    name = "elastic"

    def __post_init__(self):
        object.__setattr__(self, "k", positive("elastic stick law", "tangential_stiffness",
                                               self.k, "Pa/m (N/m^3)"))

    def stiffness(self, p):
        return np.full_like(np.asarray(p, dtype=float), self.k)

    def as_dict(self):
        return {"tangential": "elastic", "tangential_stiffness": self.k}
