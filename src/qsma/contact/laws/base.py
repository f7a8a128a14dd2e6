r"""What every interface law provides (the law of an interface, normal + tangential, is
:mod:`.interface`).

An interface law is a compliant layer in series with a rigid Coulomb slider
(docs/theory.md, "Interface laws"). Per unit area of the interface, the layer has

* a normal part, the pressure ``p(h)`` of the overclosure ``h = -w`` (``w`` the
  opening): zero up to the onset ``h_0``, then increasing. Its inverse gives the
  overclosure the layer takes under a pressure, ``h(p) >= h_0``;
* a tangential part, a stiffness ``k_t`` per unit area while the slider sticks.

The slider carries the same forces and is rigid: it is open, stuck or slipping by the
table of Coulomb's law on its own displacement, the relative displacement of the
bodies plus the deformation of the layer. A hard law has no layer (``h(p) = 0``,
``k_t`` infinite), and the slider's displacement is that of the bodies.

Laws are immutable and validated on construction; every evaluation is vectorised over
pairs. Pressures and stiffnesses are per unit area (Pa, Pa/m): a contact point of
tributary area ``A`` carries the force ``A p``.
"""
from __future__ import annotations

import math

import numpy as np

from ..._infra.deprecation import forward
from ...errors import InputError


def positive(owner, name, value, unit):
    """``value`` as a float, refused unless finite and > 0 (message names the law)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise InputError(f"{owner}: {name} must be a number in {unit}, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"{owner}: {name} must be a finite number > 0 (in {unit}), "
                         f"got {value!r}")
    return value


class NormalLaw:
    """Pressure-overclosure relation of the layer, per unit area (subclasses set the
    formulas). ``hard``: no layer. ``linear``: constant compliance (no iteration)."""

    name = "normal"
    hard = False
    linear = False

    @property
    def onset(self) -> float:
        """Overclosure ``h_0`` at which the pressure becomes positive (m)."""
        return 0.0

    def pressure(self, h):
        """``p(h)`` (Pa), zero for ``h <= onset``."""
        raise NotImplementedError

    def stiffness(self, h):
        """``dp/dh`` (Pa/m)."""
        raise NotImplementedError

    def overclosure(self, p):
        """``h(p)`` for ``p >= 0`` (``onset`` at ``p = 0``), the inverse of
        :meth:`pressure`."""
        raise NotImplementedError

    def tangent_at_pressure(self, p):
        """``dp/dh`` at the overclosure that carries ``p``."""
        return self.stiffness(self.overclosure(np.maximum(p, 0.0)))

    def scale_pressure(self) -> float:
        """A pressure typical of the law (Pa): where its layer is linearised for pairs
        that carry no pressure yet."""
        raise NotImplementedError

    def as_dict(self) -> dict:
        raise NotImplementedError


class TangentialLaw:
    """Stick stiffness per unit area of the layer (Pa/m), possibly depending on the
    pressure; ``rigid``: infinite (no tangential layer)."""

    name = "tangential"
    rigid = False

    def stiffness(self, p):
        raise NotImplementedError

    def as_dict(self) -> dict:
        raise NotImplementedError


# The law of an interface moved to :mod:`qsma.contact.laws.interface` (it defaults to the
# hard law and rigid stick, which are built on this module); the old path keeps working
# for one release, with a DeprecationWarning.
forward(__name__, names={"InterfaceLaw": "qsma.contact.laws.interface"})
