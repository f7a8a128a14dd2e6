r"""Bolts: an axial elastic member between two washer areas, pretensioned then locked
(docs/theory.md section 11).

Each end of a bolt is a reference point tied to a washer (bearing) facet set of one
body by a distributing coupling (RBE3-like): with ``w_i`` the weights of the
consistent nodal forces of a uniform traction on the washer (``sum w_i = 1``) and
``n`` the bolt axis from end a to end b, the reference point moves by
``ubar = sum_i w_i u_i`` and a force ``F`` at it is spread as ``w_i F`` over the
washer nodes. The bolt elongation and the unit-tension load are

.. math:: \ell = n \cdot (\bar u_b - \bar u_a) = c^T u, \qquad
          f_{N=1} = -c, \qquad c = [-b_a;\; b_b], \quad b_j = w \otimes n .

**Preload** (force controlled, like a pretension section in its first step): the
pretension ``N0`` is part of the 'preload' load pattern, ``N0 f_{N=1}``.
**Locked** afterwards: the bolt is a spring of stiffness ``k`` (``EA / L``) at the
length the preload left, ``N = N0 + k (\ell - \ell_{pre})``; the tied modes include
its stiffness ``k c c^T`` (the finite element quantities: :mod:`qsma.fe.bolts`).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .._infra.deprecation import forward
from ..errors import InputError


@dataclass(frozen=True)
class Bolt:
    """A pretensioned bolt between the washer facet set ``set_a`` of ``body_a`` (head)
    and ``set_b`` of ``body_b`` (nut).

    Parameters
    ----------
    name : str
    body_a, set_a, body_b, set_b : the two ends (different bodies)
    pretension : float
        Bolt tension N0 after tightening, N (N per metre of depth in 2D), > 0.
    stiffness : float
        Axial stiffness ``E A / L`` of the locked bolt, N/m (N/m per metre in 2D), > 0.
    """

    name: str
    body_a: str
    set_a: str
    body_b: str
    set_b: str
    pretension: float
    stiffness: float

    def __post_init__(self):
        for field_name in ("pretension", "stiffness"):
            v = getattr(self, field_name)
            if (not isinstance(v, (int, float, np.integer, np.floating))
                    or isinstance(v, bool) or not math.isfinite(v)):
                raise InputError(f"bolt {self.name!r}: {field_name} must be a finite "
                                 f"number, got {v!r}")
            object.__setattr__(self, field_name, float(v))
        if self.pretension <= 0:
            raise InputError(f"bolt {self.name!r}: pretension must be > 0 (the tension "
                             f"that clamps the plates, N), got {self.pretension:g}; a bolt "
                             f"cannot push the plates apart: give the magnitude")
        if self.stiffness <= 0:
            raise InputError(f"bolt {self.name!r}: stiffness must be > 0 (E A / L of the "
                             f"shank, N/m), got {self.stiffness:g}")
        if self.body_a == self.body_b:
            raise InputError(f"bolt {self.name!r}: both ends are on body {self.body_a!r}; "
                             f"a bolt joins two bodies: put set_b on the other body")

    @property
    def pattern(self) -> str:
        """Name of its unit-tension load pattern."""
        return f"bolt:{self.name}"

    @property
    def bodies(self) -> tuple:
        """The bodies it joins."""
        return (self.body_a, self.body_b)


@dataclass(frozen=True)
class SectionBolt:
    """A meshed bolt (a solid body, or part of one) cut by a pretension section: the
    facet set ``section`` of body ``body``, faces through the shank, each in the
    orientation of the cell that owns it (corners counter-clockwise seen from outside
    that cell, as a deck's element faces give them); these cells take the cut's
    copies of the section's nodes (docs/theory.md section 11).

    Force controlled in the preload (tension ``pretension`` across the section), the
    section's opening held from then on. Its stiffness is the mesh's: no ``E A / L``.

    Parameters
    ----------
    name : str
    body : str
        The body the section cuts in two.
    section : str
        Facet set of the cut (internal faces of ``body``).
    pretension : float
        Tension N0 across the section after tightening, N (N per metre in 2D), > 0.
    normal : tuple of float, optional
        Direction of the section's normal, pointing out of the cells that own its
        faces; default: their mean outward normal (the direction CalculiX takes).
    """

    name: str
    body: str
    section: str
    pretension: float
    normal: tuple | None = None

    def __post_init__(self):
        v = self.pretension
        if (not isinstance(v, (int, float, np.integer, np.floating)) or isinstance(v, bool)
                or not math.isfinite(v)):
            raise InputError(f"bolt {self.name!r}: pretension must be a finite number, "
                             f"got {v!r}")
        object.__setattr__(self, "pretension", float(v))
        if self.pretension <= 0:
            raise InputError(f"bolt {self.name!r}: pretension must be > 0 (the tension "
                             f"across the section, N), got {self.pretension:g}; give the "
                             f"magnitude")
        if self.normal is not None:
            n = np.asarray(self.normal, dtype=float).ravel()
            if n.size not in (2, 3) or not np.all(np.isfinite(n)) or not np.any(n):
                raise InputError(f"bolt {self.name!r}: normal must be 2 or 3 finite numbers, "
                                 f"not all zero, got {self.normal!r}")
            object.__setattr__(self, "normal", tuple(float(x) for x in n))

    @property
    def pattern(self) -> str:
        """Name of its unit-tension load pattern."""
        return f"bolt:{self.name}"

    @property
    def bodies(self) -> tuple:
        """The body it cuts."""
        return (self.body,)


# The bolt's loads, stiffness and elongation (finite element quantities) moved to
# :mod:`qsma.fe.bolts`; the old path keeps working for one release, with a
# DeprecationWarning.
forward(__name__, "qsma.fe.bolts")
