"""Bolted variants of the 2D lap joint: a bolt (pretension, then locked) instead of
the pressure patches (docs/validation.md).

The bolt's washers are the lap joint's 10 mm bolt patches on the two outer faces;
its pretension is the patches' resultant, 100 MPa x 10 mm = 1 MN per metre of
depth, and its locked axial stiffness per metre of depth is that of a steel shank
8 mm wide through the 10 mm grip, ``E w / L = 1.6e11`` N/m per m.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

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



#: The bolted square stack (SI units): two steel plates 2 A x 2 A of thicknesses
#: t_bottom and t_top, one bolt on the axis x = z = 0 with a square washer a x a on
#: each outer face, pretension N0 and the stiffness of an M8 shank (50 mm^2) through
#: the 8 mm grip. Elements A / (n_plane refine) in the plane, n_thick refine through
#: each plate.
STACK_3D = dict(A=0.015, t_bottom=0.005, t_top=0.003, a_washer=0.010, pretension=8000.0,
                stiffness=200e9 * 50e-6 / 0.008, E=200e9, nu=0.3, rho=7850.0, mu=0.6,
                n_plane=6, n_thick=2)


def stack_3d_bolted(refine: int = 1, mu: float | None = None):
    """A bolted square stack of two plates, for the preload compared with CalculiX
    (docs/validation.md, benchmarks/bench_bolt_calculix.py).

    The bottom plate is held by three of its outer-face corners, statically
    determinate (3-2-1: ``(-A, 0, -A)`` in x, y, z; ``(A, 0, -A)`` in y, z;
    ``(-A, 0, A)`` in y), so these supports carry no load under the pretension (it
    is self-equilibrated). The top plate is held only by the joint, so the contact
    force equals the bolt force. The plates differ in thickness so that the
    interface slips a little under the preload (friction matters).
    """
    from ..model import Body, Clamp, Interface, Material, Model
    from ..mesh.generate import structured_mesh
    from .lap import _check_refine
    _check_refine(refine)
    s = STACK_3D
    A, h = s["A"], s["a_washer"] / 2
    eps = 1e-9 * A
    plane = np.linspace(-A, A, 2 * s["n_plane"] * refine + 1)
    steel = Material(s["E"], s["nu"], s["rho"])
    bodies = []
    for name, y0, t in (("bottom", 0.0, s["t_bottom"]),
                        ("top", s["t_bottom"], s["t_top"])):
        mesh = structured_mesh(plane, np.linspace(y0, y0 + t, s["n_thick"] * refine + 1),
                               plane)
        y_if, y_out = (y0 + t, y0) if name == "bottom" else (y0, y0 + t)
        on = lambda y: (lambda p: np.abs(p[:, 1] - y) < eps)
        facet_sets = {
            "interface": mesh.boundary_facets_where(on(y_if)),
            "washer": mesh.boundary_facets_where(
                lambda q: on(y_out)(q) & (np.abs(q[:, 0]) < h + eps)
                & (np.abs(q[:, 2]) < h + eps))}
        node_sets, clamps = {}, []
        if name == "bottom":
            corner = lambda x, z: np.flatnonzero(
                (np.abs(mesh.points - (x, y_out, z)) < eps).all(axis=1))
            node_sets = {"support_xyz": corner(-A, -A), "support_yz": corner(A, -A),
                         "support_y": corner(-A, A)}
            clamps = [Clamp("support_xyz"), Clamp("support_yz", (1, 2)),
                      Clamp("support_y", (1,))]
        mesh = mesh.with_sets(node_sets=node_sets, facet_sets=facet_sets)
        bodies.append(Body(name, mesh, steel, clamps=tuple(clamps)))
    bolt = Bolt("bolt", "bottom", "washer", "top", "washer", s["pretension"],
                s["stiffness"])
    return Model(bodies=tuple(bodies),
                 interface=Interface("bottom", "interface", "top", "interface"),
                 bolts=(bolt,), mu=s["mu"] if mu is None else mu,
                 name=f"stack-3d-bolted (refine={refine})")
