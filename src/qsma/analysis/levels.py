"""Load levels of the modal ramp: by modal force alpha or by linear tip deflection."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

KINDS = ("alpha", "tip")
#: Most load levels of one run: 200 times the 51 levels of the sandwich-2d spec. The
#: ramp solves one contact problem per level and keeps every level's contact state
#: (3 ms per level on sandwich-2d, `qsma run --example sandwich-2d --levels
#: tip:log:1e-6:1e-3:5`: contact 0.015 s), so 10^4 levels already take about 30 s
#: there and hours on 3D models; a larger count is a typo (n = 10^10 levels would
#: allocate 74.5 GiB for their values alone).
MAX_LEVELS = 10_000


@dataclass(frozen=True)
class Levels:
    """Increasing positive load levels.

    ``kind="alpha"``: values are modal forces alpha directly. ``kind="tip"``: values
    are tip deflections of the *linear tied* structure, ``alpha = tip * w0^2 / phi_tip``.
    """

    kind: str
    values: tuple

    def __post_init__(self):
        if self.kind not in KINDS:
            raise InputError(f"load level kind must be one of {KINDS}, got {self.kind!r}")
        v = np.asarray(self.values, dtype=float).ravel()
        _count_check(v.size)
        if v.size == 0:
            raise InputError("at least one load level is needed")
        if not np.all(np.isfinite(v)):
            raise InputError("load levels must be finite numbers")
        if np.any(v <= 0):
            raise InputError(f"load levels must be > 0, got {v[v <= 0][:3].tolist()}")
        if np.any(np.diff(v) <= 0):
            k = int(np.flatnonzero(np.diff(v) <= 0)[0])
            raise InputError(f"load levels must increase strictly (the ramp is monotonic): "
                             f"level {k + 1} = {v[k + 1]:g} follows {v[k]:g}")
        object.__setattr__(self, "values", tuple(v.tolist()))

    @classmethod
    def log(cls, kind, start, stop, n):
        _range_check(start, stop, n)
        return cls(kind, tuple(np.logspace(np.log10(start), np.log10(stop), int(n))))

    @classmethod
    def linear(cls, kind, start, stop, n):
        _range_check(start, stop, n)
        return cls(kind, tuple(np.linspace(start, stop, int(n))))

    def alpha(self, omega0: float, phi_tip: float) -> np.ndarray:
        """Modal force levels."""
        v = np.asarray(self.values)
        if self.kind == "alpha":
            return v
        return v * omega0 ** 2 / phi_tip


def _count_check(n):
    if n > MAX_LEVELS:
        raise InputError(f"{n} load levels asked; at most {MAX_LEVELS} are allowed (each "
                         f"level is a contact solve whose state is kept; the benchmark "
                         f"uses 51): lower n")


def _range_check(start, stop, n):
    if not (isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 1):
        raise InputError(f"number of levels must be a positive integer, got {n!r}")
    _count_check(n)
    if not (np.isfinite(start) and np.isfinite(stop) and 0 < start):
        raise InputError(f"level range needs 0 < start < stop, got start={start}, stop={stop}")
    if n == 1 and start != stop:
        raise InputError(f"one level (n = 1) from start={start} to stop={stop}: the level "
                         f"would be start and stop ignored; give start = stop, or the "
                         f"level as a list (spacing 'list', values = [...])")
    if n > 1 and not start < stop:
        raise InputError(f"level range needs 0 < start < stop, got start={start}, stop={stop}")


def spec_levels(units="SI") -> Levels:
    """The 51 levels of sandwich-2d: linear tied tip deflection 10^(-6 + 3k/50) m, in
    the length unit of ``units`` (1 um to 1 mm: 1e-3 to 1 in a millimetre model)."""
    from ..units import unit_system
    metres = 10.0 ** (-6 + 3 * np.arange(51) / 50)
    return Levels("tip", tuple(metres / unit_system(units).length_m))
