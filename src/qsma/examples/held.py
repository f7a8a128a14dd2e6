"""The 2D lap joint held only through its joint: cantilever and free-free forms.

``lap_2d_cantilever``: the bottom plate clamped at its far end, the top plate held
only by the bolted overlap (friction and the bolt pressure), a cantilever whose
first bending mode loads the joint. ``lap_2d_free``: no clamp at all (a free-free
structure, as the Brake-Reuss beam is tested); the two bolt pressure patches are
equal and opposite, so the preload is self-equilibrated. Geometry, material and
bolt of :data:`qsma.examples.lap.LAP_2D` (docs/validation.md).
"""
from __future__ import annotations

from dataclasses import replace

from .lap import lap_2d


def lap_2d_cantilever(refine: int = 1, mu: float | None = None):
    """:func:`qsma.examples.lap_2d` with the top plate's clamp removed."""
    m = lap_2d(refine, mu)
    bottom, top = m.bodies
    return replace(m, bodies=(bottom, replace(top, clamps=())),
                   name=f"lap-2d-cantilever (refine={refine})")


def lap_2d_free(refine: int = 1, mu: float | None = None):
    """:func:`qsma.examples.lap_2d` with both clamps removed (free-free)."""
    m = lap_2d(refine, mu)
    return replace(m, bodies=tuple(replace(b, clamps=()) for b in m.bodies),
                   name=f"lap-2d-free (refine={refine})")
