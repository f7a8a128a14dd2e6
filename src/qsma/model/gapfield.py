"""Initial gap fields of interfaces: the shape of the surfaces, as an input.

A flat mesh gives a flat interface: every pair touches at once. Real lap joints are
curved on the scale of the lap (machining, clamping) and touch first near the bolts;
a gap field per interface puts that shape into the contact problem as the initial
normal gap ``g0`` of every contact point (positive apart). It is a function of the
contact points' coordinates: any callable, or a :class:`GapField` interpolating
samples, such as a measured height map read by :func:`read_gap_field`.
"""
from __future__ import annotations

from dataclasses import dataclass
import csv
import os

import numpy as np

from ..errors import InputError

AXES = ("x", "y", "z")


@dataclass(frozen=True, eq=False)
class GapField:
    """The initial gap over an interface, interpolated linearly from samples.

    Parameters
    ----------
    axes : tuple of str
        The global coordinates the samples are given in (one in 2D, two in 3D), e.g.
        ``("x", "z")`` for an interface normal to ``y``.
    points : (m, len(axes)) sample coordinates (m)
    values : (m,) value at each sample (m)
    kind : {"gap", "height"}
        ``"gap"``: the values are the gap itself. ``"height"``: the combined height of
        the two surfaces towards each other (the sum of each surface's protrusion
        towards the other body); the gap is then ``max(height) - height`` over the
        contact points, so that the surfaces touch first at their highest point.
    source : where the samples came from (messages)
    """

    axes: tuple
    points: np.ndarray
    values: np.ndarray
    kind: str = "gap"
    source: str = "gap field"

    def __post_init__(self):
        axes = tuple(self.axes)
        if not axes or len(axes) > 2 or any(a not in AXES for a in axes) \
                or len(set(axes)) != len(axes):
            raise InputError(f"{self.source}: axes must be one or two of {AXES}, got "
                             f"{axes!r}")
        pts = np.asarray(self.points, dtype=float).reshape(len(self.values), -1)
        vals = np.asarray(self.values, dtype=float).ravel()
        if pts.shape != (len(vals), len(axes)):
            raise InputError(f"{self.source}: expected {len(axes)} coordinate(s) per "
                             f"sample, got shape {pts.shape}")
        if len(vals) < len(axes) + 1:
            raise InputError(f"{self.source}: {len(vals)} sample(s) cannot cover an "
                             f"interface; give at least {len(axes) + 1}")
        if not (np.all(np.isfinite(pts)) and np.all(np.isfinite(vals))):
            raise InputError(f"{self.source}: the samples hold NaN/Inf")
        if self.kind not in ("gap", "height"):
            raise InputError(f"{self.source}: kind must be 'gap' or 'height', got "
                             f"{self.kind!r}")
        object.__setattr__(self, "axes", axes)
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "values", vals)

    def __call__(self, x):
        """Gaps at the points ``x`` (n, dim); refused where ``x`` lies outside the
        samples (no extrapolation)."""
        x = np.asarray(x, dtype=float)
        cols = [AXES.index(a) for a in self.axes]
        if max(cols) >= x.shape[1]:
            raise InputError(f"{self.source}: axis {self.axes[-1]!r} does not exist in a "
                             f"{x.shape[1]}D model")
        at = x[:, cols]
        if len(cols) == 1:
            order = np.argsort(self.points[:, 0])
            xs, vs = self.points[order, 0], self.values[order]
            v = np.interp(at[:, 0], xs, vs)
            span = max(xs[-1] - xs[0], np.finfo(float).tiny)
            v[(at[:, 0] < xs[0] - 1e-9 * span) | (at[:, 0] > xs[-1] + 1e-9 * span)] = np.nan
        else:
            # imported here: scipy.interpolate brings scipy.optimize, 0.1-0.2 s of the
            # start of every command, and only a 2D gap field needs it
            from scipy.interpolate import LinearNDInterpolator
            v = LinearNDInterpolator(self.points, self.values)(at)
        outside = ~np.isfinite(v)
        if outside.any():
            k = int(np.argmax(outside))
            raise InputError(
                f"{self.source}: {int(outside.sum())} of {len(v)} contact points lie "
                f"outside the samples (e.g. at {dict(zip(self.axes, at[k].tolist()))}); "
                f"a gap field must cover the whole interface. Fix: extend the samples "
                f"over the interface, or check the axes {self.axes} and the units (m)")
        return v.max() - v if self.kind == "height" else v


def read_gap_field(path, scale=1.0, coordinate_scale=1.0) -> GapField:
    """A :class:`GapField` from a CSV file with a header row naming the coordinate
    columns (``x``, ``y`` or ``z``, one in 2D, two in 3D) and one value column named
    ``gap`` or ``height`` (``kind`` follows the name). ``scale`` multiplies the values
    (e.g. 1e-6 for heights in micrometres), ``coordinate_scale`` the coordinates (1e-3
    for millimetres), so that both are in the model's units."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"gap field {path!r}: not a regular file")
    for name, v in (("scale", scale), ("coordinate_scale", coordinate_scale)):
        if isinstance(v, bool) or not (isinstance(v, (int, float)) and np.isfinite(v)
                                       and v > 0):
            raise InputError(f"gap field {path!r}: {name} must be a positive number, got "
                             f"{v!r}")
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = [r for r in csv.reader(f) if r and not r[0].lstrip().startswith("#")]
    except (UnicodeDecodeError, OSError) as exc:
        raise InputError(f"gap field {path!r}: cannot be read as UTF-8 CSV ({exc})") from None
    if len(rows) < 2:
        raise InputError(f"gap field {path!r}: needs a header row and samples")
    header = [h.strip().lower() for h in rows[0]]
    value = [h for h in header if h in ("gap", "height")]
    axes = tuple(h for h in header if h in AXES)
    extra = [h for h in header if h not in AXES + ("gap", "height")]
    if len(value) != 1 or extra or len(set(header)) != len(header):
        raise InputError(f"gap field {path!r}: the header must name the coordinate "
                         f"columns (x, y, z) and one of 'gap' or 'height', got {rows[0]}")
    try:
        data = np.array([[float(v) for v in r] for r in rows[1:]], dtype=float)
    except ValueError as exc:
        raise InputError(f"gap field {path!r}: a row is not numbers ({exc})") from None
    if data.shape[1] != len(header):
        raise InputError(f"gap field {path!r}: rows of {data.shape[1]} values for a "
                         f"header of {len(header)}")
    cols = [header.index(a) for a in axes]
    return GapField(axes, data[:, cols] * coordinate_scale,
                    data[:, header.index(value[0])] * scale,
                    kind=value[0], source=f"gap field {path!r}")
