"""Linear (viscous) damping of the structure besides the joint.

The joint's damping comes from friction (qsma's loops and Masing's rules); the rest of
the structure dissipates too (material, suspension, air). A test measures both at once,
so a prediction is compared with a measurement on the same footing only with that
linear part added. It is an input, measured on the structure (e.g. at an amplitude too
small to slip) or taken from a similar one; qsma reports it beside the joint's damping
and adds the two (equivalent viscous damping ratios of the mode add).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

from ..errors import InputError

#: Largest linear damping ratio accepted: structures with joints are lightly damped
#: (0.01 % to a few %); 0.5 means a ratio typed as a percentage (50 for 0.5 %).
RATIO_MAX = 0.5


@dataclass(frozen=True)
class LinearDamping:
    r"""A modal damping ratio, or Rayleigh damping ``C = a M + b K``.

    ``ratio`` alone: the mode's damping ratio (dimensionless, e.g. 0.00087 for
    0.087 %). ``alpha``/``beta`` (1/s and s): Rayleigh, whose ratio at the circular
    frequency ``w`` is :math:`\zeta = \alpha / (2 w) + \beta w / 2` (evaluated at each
    level's secant frequency).
    """

    ratio: float | None = None
    alpha: float = 0.0
    beta: float = 0.0

    def __post_init__(self):
        if self.ratio is not None and (self.alpha or self.beta):
            raise InputError("linear damping: give a modal damping ratio or Rayleigh "
                             "alpha/beta, not both")
        for name, unit in (("ratio", ""), ("alpha", " (1/s)"), ("beta", " (s)")):
            v = getattr(self, name)
            if v is None:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) \
                    or not math.isfinite(v) or v < 0:
                raise InputError(f"linear damping: {name}{unit} must be a finite number "
                                 f">= 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.ratio is not None and self.ratio > RATIO_MAX:
            raise InputError(f"linear damping: ratio = {self.ratio:g} is a damping ratio "
                             f"above {RATIO_MAX:g}; give it as a fraction of critical "
                             f"(0.00087 for 0.087 %), not in percent")

    def zeta(self, omega):
        """Damping ratio at circular frequency ``omega`` (rad/s; array or scalar)."""
        if self.ratio is not None:
            return self.ratio + 0.0 * omega
        return self.alpha / (2.0 * omega) + 0.5 * self.beta * omega

    def as_dict(self) -> dict:
        if self.ratio is not None:
            return {"ratio": self.ratio}
        return {"rayleigh": [self.alpha, self.beta]}
