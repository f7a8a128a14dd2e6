r"""What every interface law provides, and the law of an interface (normal + tangential).

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

from dataclasses import dataclass, field
import math

import numpy as np

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


@dataclass(frozen=True)
class InterfaceLaw:
    """The law of an interface: a normal and a tangential part.

    ``InterfaceLaw()`` is the hard law with rigid stick (rigid Coulomb contact).
    ``tangential=None`` takes the tangential part the normal law implies
    (:class:`qsma.contact.laws.RoughSurface` gives its own stick stiffness), else rigid
    stick.
    """

    normal: NormalLaw = None
    tangential: TangentialLaw | None = None
    label: str = field(default="", compare=False)

    def __post_init__(self):
        from .hard import Hard
        from .tangential import RigidStick
        normal = Hard() if self.normal is None else self.normal
        if not isinstance(normal, NormalLaw):
            raise InputError(f"interface law: normal must be a normal law "
                             f"(Hard, LinearPressure, ExponentialPressure, TabularPressure, "
                             f"RoughSurface), got {type(normal).__name__}")
        tangential = self.tangential
        if tangential is None:
            tangential = getattr(normal, "stick", None) or RigidStick()
        if not isinstance(tangential, TangentialLaw):
            raise InputError(f"interface law: tangential must be a tangential law "
                             f"(RigidStick, ElasticStick), got {type(tangential).__name__}")
        object.__setattr__(self, "normal", normal)
        object.__setattr__(self, "tangential", tangential)

    @property
    def rigid(self) -> bool:
        """Hard normal contact and rigid stick: the slider is the interface."""
        return self.normal.hard and self.tangential.rigid

    def as_dict(self) -> dict:
        """The law as the plain table of results.json and the TOML input."""
        return {**self.normal.as_dict(), **self.tangential.as_dict()}
