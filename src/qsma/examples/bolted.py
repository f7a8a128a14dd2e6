"""Bolted variants of the 2D lap joint: a bolt (pretension, then locked) instead of
the pressure patches (docs/validation.md).

The bolt's washers are the lap joint's 10 mm bolt patches on the two outer faces;
its pretension is the patches' resultant, 100 MPa x 10 mm = 1 MN per metre of
depth, and its locked axial stiffness per metre of depth is that of a steel shank
8 mm wide through the 10 mm grip, ``E w / L = 1.6e11`` N/m per m.
"""
from __future__ import annotations

from dataclasses import replace

from ..model import Bolt
from .lap import LAP_2D, lap_2d

#: Bolt of the bolted 2D lap joint (per metre of depth): pretension N, stiffness N/m.
BOLT_2D = dict(pretension=LAP_2D["p_bolt"] * LAP_2D["w_bolt"],
               stiffness=LAP_2D["E"] * 0.008 / (2 * LAP_2D["t"]))


def lap_2d_bolted(refine: int = 1, mu: float | None = None, free: str = "none",
                  pretension: float | None = None):
    """:func:`qsma.examples.lap_2d` with a bolt between the two washer patches.

    ``free``: ``"none"`` (both plates clamped at their far ends), ``"top"`` (the top
    plate held only by the joint: a cantilever) or ``"all"`` (free-free).
    """
    m = lap_2d(refine, mu)
    unclamp = {"none": (), "top": ("top",), "all": ("bottom", "top")}[free]
    bodies = tuple(replace(b, pressures=(), clamps=() if b.name in unclamp else b.clamps)
                   for b in m.bodies)
    bolt = Bolt("bolt", "bottom", "bolt", "top", "bolt",
                BOLT_2D["pretension"] if pretension is None else pretension,
                BOLT_2D["stiffness"])
    return replace(m, bodies=bodies, bolts=(bolt,),
                   name=f"lap-2d-bolted (refine={refine}, free={free})")

#: Bolt of the bolted 3D lap joint: the lap_3d bolt force, an M8 shank (50 mm^2)
#: through the 10 mm grip.
BOLT_3D = dict(pretension=8000.0, stiffness=200e9 * 50e-6 / 0.010)


def lap_3d_bolted(refine: int = 1, mu: float | None = None):
    """:func:`qsma.examples.lap_3d` (both plates clamped at their far ends) with a bolt
    between the two 10 mm x 10 mm washer patches instead of the pressure patches."""
    from .lap import lap_3d
    m = lap_3d(refine, mu)
    bodies = tuple(replace(b, pressures=()) for b in m.bodies)
    bolt = Bolt("bolt", "bottom", "bolt", "top", "bolt", BOLT_3D["pretension"],
                BOLT_3D["stiffness"])
    return replace(m, bodies=bodies, bolts=(bolt,), name=f"lap-3d-bolted (refine={refine})")


def sandwich_2d_bolted(refine: int = 1, mu: float | None = None):
    """:func:`qsma.examples.sandwich_2d` with a bolt between its two bolt patches
    instead of the pressures: pretension = the patches' resultant (17.554 MPa x
    6.35 mm = 111.47 kN per m), locked stiffness ``E w / L`` of a shank as wide as the
    patch through the 12.7 mm grip (1.0e11 N/m per m)."""
    from .sandwich import SANDWICH_2D, sandwich_2d
    s = SANDWICH_2D
    m = sandwich_2d(refine, mu)
    bodies = tuple(replace(b, pressures=()) for b in m.bodies)
    bolt = Bolt("bolt", m.bodies[0].name, "bolt", m.bodies[1].name, "bolt",
                s["p_bolt"] * s["w_bolt"], s["E"] * s["w_bolt"] / (2 * s["h"]))
    return replace(m, bodies=bodies, bolts=(bolt,),
                   name=f"sandwich-2d-bolted (refine={refine})")
