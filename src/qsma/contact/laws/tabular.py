"""Tabular (piecewise-linear) pressure-overclosure contact."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from .base import NormalLaw


@dataclass(frozen=True)
class TabularPressure(NormalLaw):
    """Pressure-overclosure by a table, as Abaqus and CalculiX
    ``*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=TABULAR`` give it: rows
    ``(pressure, overclosure)``, the first with zero pressure (the onset, which may be
    a clearance: negative overclosure), pressures strictly increasing after it;
    linear between the rows, the last slope continued beyond the last row.

    Parameters
    ----------
    table : sequence of (pressure [Pa], overclosure [m]) rows, at least two
    """

    table: tuple

    name = "tabular"

    def __post_init__(self):
        rows = self.table
        try:
            t = np.array(rows, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"tabular pressure-overclosure law: table must be rows of "
                             f"(pressure, overclosure) numbers, got {rows!r}") from None
        if t.ndim != 2 or t.shape[1] != 2 or t.shape[0] < 2:
            raise InputError(f"tabular pressure-overclosure law: table must have at least "
                             f"two rows of (pressure, overclosure), got shape {t.shape}")
        if not np.all(np.isfinite(t)):
            raise InputError("tabular pressure-overclosure law: the table holds NaN/Inf")
        p, h = t[:, 0], t[:, 1]
        if p[0] != 0.0:
            raise InputError(f"tabular pressure-overclosure law: the first row must have "
                             f"zero pressure (the overclosure at which contact begins), "
                             f"got pressure {p[0]:g}")
        if np.any(np.diff(p) <= 0) or np.any(np.diff(h) <= 0):
            k = int(np.argmax((np.diff(p) <= 0) | (np.diff(h) <= 0)))
            raise InputError(f"tabular pressure-overclosure law: pressure and overclosure "
                             f"must both increase strictly from row to row (a stiffer "
                             f"contact the more it is pressed), rows {k} and {k + 1} are "
                             f"{tuple(t[k])} and {tuple(t[k + 1])}")
        object.__setattr__(self, "table", tuple(map(tuple, t.tolist())))
        object.__setattr__(self, "_p", p)
        object.__setattr__(self, "_h", h)
        object.__setattr__(self, "_slope", np.diff(p) / np.diff(h))

    @property
    def onset(self):
        return float(self._h[0])

    def _segment(self, x, nodes):
        return np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, len(nodes) - 2)

    def pressure(self, h):
        h = np.asarray(h, dtype=float)
        j = self._segment(h, self._h)
        p = self._p[j] + self._slope[j] * (h - self._h[j])
        return np.where(h > self._h[0], p, 0.0)

    def stiffness(self, h):
        h = np.asarray(h, dtype=float)
        return np.where(h > self._h[0], self._slope[self._segment(h, self._h)], 0.0)

    def overclosure(self, p):
        p = np.maximum(np.asarray(p, dtype=float), 0.0)
        j = self._segment(p, self._p)
        return self._h[j] + (p - self._p[j]) / self._slope[j]

    def tangent_at_pressure(self, p):
        return self._slope[self._segment(np.maximum(np.asarray(p, dtype=float), 0.0),
                                         self._p)]

    def scale_pressure(self):
        return float(self._p[-1])

    def as_dict(self):
        return {"normal": "tabular", "table": [list(r) for r in self.table]}
