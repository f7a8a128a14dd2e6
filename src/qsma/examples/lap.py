"""A bolted lap joint of two steel plates: the joint whose backbone stiffens.

Two plates of thickness ``t`` overlap by ``c`` and are clamped at their far ends
(clamped-clamped, the first bending mode loads the joint). The bolt is a pressure
patch on the outer faces in the middle of the overlap. The preload closes the
interface only around the bolt; under the modal load the plates roll on each other
and pairs that were open close, so the secant stiffness rises and Masing's rules
(which assume the unloading curve is the backbone scaled by two) give a wrong and
even negative dissipation: qsma computes the loops (docs/validation.md).

All numbers are chosen here (SI units); the 3D variant adds a width and a square
washer footprint.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..model import Body, Clamp, Interface, Material, Model, Pressure, Probe
from ..mesh.generate import graded_axis, structured_mesh

#: Parameters of the lap joints (SI units). Element sizes at refine 1: 1 mm in the
#: overlap, 2 mm elsewhere, 4 elements through the thickness (2D).
LAP_2D = dict(L=0.100, t=0.005, c=0.030, w_bolt=0.010, p_bolt=100e6, E=200e9, nu=0.3,
              rho=7850.0, mu=0.6, n_thick=4, n_outer=35, n_overlap=30)
#: 3D: width b, square washer a x a; 2 mm in the overlap, 5 mm elsewhere, 2 elements
#: through the thickness and 10 across the width at refine 1.
LAP_3D = dict(L=0.100, t=0.005, b=0.020, c=0.030, a_washer=0.010, bolt_force=8000.0,
              E=200e9, nu=0.3, rho=7850.0, mu=0.6, n_thick=2, n_outer=14, n_overlap=15,
              n_width=10)


def _check_refine(refine):
    if not isinstance(refine, (int, np.integer)) or refine < 1:
        raise InputError(f"refine must be a positive integer, got {refine!r}")


def _plate_axis(s, refine, bottom, n_overlap=None):
    """x grid of one plate: the overlap finer than the free length."""
    L, c = s["L"], s["c"]
    n = (s["n_overlap"] if n_overlap is None else n_overlap) * refine
    if bottom:
        return graded_axis((0.0, L - c, s["n_outer"] * refine), (L - c, L, n))
    return graded_axis((L - c, L, n), (L, 2 * L - c, s["n_outer"] * refine))


def _sets(mesh, s, y_if, y_out, x_clamp, patch):
    eps = 1e-9 * s["L"]
    L, c = s["L"], s["c"]
    on = lambda y: (lambda p: np.abs(p[:, 1] - y) < eps)
    xb = L - c / 2
    facet_sets = {
        "interface": mesh.boundary_facets_where(
            lambda p: on(y_if)(p) & (p[:, 0] >= L - c - eps) & (p[:, 0] <= L + eps)),
        "bolt": mesh.boundary_facets_where(lambda p: on(y_out)(p) & patch(p)),
    }
    dx = np.diff(np.unique(mesh.points[:, 0])).min()
    node_sets = {"clamp": np.flatnonzero(np.abs(mesh.points[:, 0] - x_clamp) < eps),
                 "probe": np.flatnonzero(np.abs(mesh.points[:, 0] - xb) < 0.5 * dx + eps)}
    return mesh.with_sets(node_sets=node_sets, facet_sets=facet_sets)


def lap_2d(refine: int = 1, mu: float | None = None, top_overlap_elements=None) -> Model:
    """The 2D lap joint (plane strain, unit depth): two plates 100 mm x 5 mm overlapping
    by 30 mm, clamped at their far ends, bolt pressure 100 MPa over 10 mm in the middle
    of the overlap. The probe is the mean vertical displacement of the nodes on the
    bolt axis (mid-span; the grid lines next to it where no grid line lies on it).
    ``top_overlap_elements``: elements of the top plate along the overlap (default 30,
    as the bottom plate): another count meshes the two sides of the interface apart
    (the mortar coupling joins them)."""
    _check_refine(refine)
    s = LAP_2D
    t, L, c = s["t"], s["L"], s["c"]
    xb = L - c / 2
    patch = lambda p: np.abs(p[:, 0] - xb) <= s["w_bolt"] / 2 + 1e-9 * L
    steel = Material(s["E"], s["nu"], s["rho"])
    bodies = []
    for name, bottom in (("bottom", True), ("top", False)):
        y0 = 0.0 if bottom else t
        mesh = structured_mesh(_plate_axis(s, refine, bottom,
                                           None if bottom else top_overlap_elements),
                               np.linspace(y0, y0 + t, s["n_thick"] * refine + 1))
        mesh = _sets(mesh, s, y_if=t, y_out=0.0 if bottom else 2 * t,
                     x_clamp=0.0 if bottom else 2 * L - c, patch=patch)
        bodies.append(Body(name, mesh, steel, clamps=(Clamp("clamp"),),
                           pressures=(Pressure("bolt", s["p_bolt"]),)))
    return Model(bodies=tuple(bodies),
                 interface=Interface("bottom", "interface", "top", "interface"),
                 tip=Probe(sets=(("bottom", "probe"), ("top", "probe")), direction=(0.0, 1.0)),
                 mu=s["mu"] if mu is None else mu, name=f"lap-2d (refine={refine})")


def lap_3d(refine: int = 1, mu: float | None = None) -> Model:
    """The 3D lap joint: the 2D geometry 20 mm wide, hexahedra, bolt force 8 kN on a
    10 mm x 10 mm washer footprint on each outer face."""
    _check_refine(refine)
    s = LAP_3D
    t, L, c, b, a = s["t"], s["L"], s["c"], s["b"], s["a_washer"]
    xb = L - c / 2
    patch = lambda p: ((np.abs(p[:, 0] - xb) <= a / 2 + 1e-9 * L)
                       & (np.abs(p[:, 2] - b / 2) <= a / 2 + 1e-9 * L))
    steel = Material(s["E"], s["nu"], s["rho"])
    bodies = []
    for name, bottom in (("bottom", True), ("top", False)):
        y0 = 0.0 if bottom else t
        mesh = structured_mesh(_plate_axis(s, refine, bottom),
                               np.linspace(y0, y0 + t, s["n_thick"] * refine + 1),
                               np.linspace(0.0, b, s["n_width"] * refine + 1))
        mesh = _sets(mesh, s, y_if=t, y_out=0.0 if bottom else 2 * t,
                     x_clamp=0.0 if bottom else 2 * L - c, patch=patch)
        bodies.append(Body(name, mesh, steel, clamps=(Clamp("clamp"),),
                           pressures=(Pressure("bolt", s["bolt_force"] / a ** 2),)))
    return Model(bodies=tuple(bodies),
                 interface=Interface("bottom", "interface", "top", "interface"),
                 tip=Probe(sets=(("bottom", "probe"), ("top", "probe")),
                           direction=(0.0, 1.0, 0.0)),
                 mu=s["mu"] if mu is None else mu, name=f"lap-3d (refine={refine})")
