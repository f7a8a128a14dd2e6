"""The law of an interface: a normal and a tangential part (hard contact with rigid stick
unless told otherwise)."""
from __future__ import annotations

from dataclasses import dataclass, field

from ...errors import InputError
from .base import NormalLaw, TangentialLaw
from .hard import Hard
from .tangential import RigidStick


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
