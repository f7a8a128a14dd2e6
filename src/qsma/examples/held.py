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

from ..model import Spring
from .lap import lap_2d


def lap_2d_cantilever(refine: int = 1, mu: float | None = None,
                      spring: float | None = None):
    """:func:`qsma.examples.lap_2d` with the top plate's clamp removed.

    ``spring``: if given, the top plate's far end (its former clamp, the nodes at
    x = 170 mm) rests on grounded springs of total stiffness ``spring`` N/m per metre
    of depth in x and in y, shared equally by the nodes
    (:class:`qsma.model.Spring`): 0 < spring << 1.8e7 N/m (the plate's own
    cantilever stiffness 3 E I / l^3 over its free 70 mm) is nearly free, spring
    >> 1.4e10 N/m (its axial stiffness E t / l) nearly clamped.
    """
    m = lap_2d(refine, mu)
    bottom, top = m.bodies
    springs = () if spring is None else (Spring("clamp", (spring, spring)),)
    name = f"lap-2d-cantilever (refine={refine}" + (
        ")" if spring is None else f", spring={spring:g} N/m)")
    return replace(m, bodies=(bottom, replace(top, clamps=(), springs=springs)), name=name)


def lap_2d_free(refine: int = 1, mu: float | None = None):
    """:func:`qsma.examples.lap_2d` with both clamps removed (free-free)."""
    m = lap_2d(refine, mu)
    return replace(m, bodies=tuple(replace(b, clamps=()) for b in m.bodies),
                   name=f"lap-2d-free (refine={refine})")
