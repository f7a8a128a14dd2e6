"""The sandwich-2d benchmark: two clamped beams joined by a bolt near the tip.

Every number below is fixed by the benchmark definition in docs/benchmarks.md.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import InputError
from ..model import Body, Clamp, Interface, Material, Model, Pressure, Probe
from ..mesh.generate import graded_axis, structured_mesh

#: parameters of the spec (SI units)
SANDWICH_2D = dict(
    L=0.2032, h=0.00635, contact_length=0.0508, E=200e9, nu=0.285, rho=6600.0,
    p_bolt=17.554e6, x_bolt=0.2032 - 0.0254, w_bolt=0.00635, mu=0.6,
    n_thick=8, n_coarse=60, n_fine=64,
)


#: element option of the examples -> (cell type, element name for Mesh.element);
#: ``None`` element name: qsma's default formulation (full integration)
ELEMENTS_2D = {
    "quad": ("quad", None), "CPE4": ("quad", "CPE4"), "CPE4I": ("quad", "CPE4I"),
    "quad8": ("quad8", None), "CPE8": ("quad8", "CPE8"), "CPE8R": ("quad8", "CPE8R"),
    "quad9": ("quad9", None),
}
ELEMENTS_3D = {
    "hexahedron": ("hexahedron", None), "C3D8": ("hexahedron", "C3D8"),
    "C3D8I": ("hexahedron", "C3D8I"), "hexahedron20": ("hexahedron20", None),
    "C3D20": ("hexahedron20", "C3D20"), "C3D20R": ("hexahedron20", "C3D20R"),
    "hexahedron27": ("hexahedron27", None),
    "C3D27": ("hexahedron27", "C3D27"),
}


def _element(element, table):
    if element not in table:
        raise InputError(f"element must be one of {sorted(table)}, got {element!r}")
    return table[element]


def _beam(y0, refine, top, element="quad"):
    s = SANDWICH_2D
    L, h, lc = s["L"], s["h"], s["contact_length"]
    xs = graded_axis((0.0, L - lc, s["n_coarse"] * refine), (L - lc, L, s["n_fine"] * refine))
    ys = np.linspace(y0, y0 + h, s["n_thick"] * refine + 1)
    cell_type, name = _element(element, ELEMENTS_2D)
    mesh = structured_mesh(xs, ys, cell_type=cell_type)
    eps = 1e-9 * L
    xb0, xb1 = s["x_bolt"] - s["w_bolt"] / 2, s["x_bolt"] + s["w_bolt"] / 2
    y_if = y0 if top else y0 + h            # face y = h of both beams
    y_bolt = y0 + h if top else y0          # outer face
    on = lambda y: (lambda p: np.abs(p[:, 1] - y) < eps)
    facet_sets = {
        "interface": mesh.boundary_facets_where(
            lambda p: on(y_if)(p) & (p[:, 0] >= L - lc - eps)),
        "bolt": mesh.boundary_facets_where(
            lambda p: on(y_bolt)(p) & (p[:, 0] >= xb0 - eps) & (p[:, 0] <= xb1 + eps)),
        "outer": mesh.boundary_facets_where(on(y_bolt)),
        "end": mesh.boundary_facets_where(lambda p: np.abs(p[:, 0] - L) < eps),
    }
    node_sets = {"clamp": np.flatnonzero(np.abs(mesh.points[:, 0]) < eps),
                 "tip": np.flatnonzero(np.abs(mesh.points[:, 0] - L) < eps)}
    return dataclasses.replace(mesh, element=name).with_sets(node_sets=node_sets,
                                                             facet_sets=facet_sets)


def sandwich_2d(refine: int = 1, mu: float | None = None, element: str = "quad") -> Model:
    """The sandwich-2d model at refinement level ``refine`` (every element divided
    ``refine x refine``; 2250 nodes and 65 interface pairs at ``refine=1``).

    ``element`` (a key of ``ELEMENTS_2D``): ``"quad"`` (default, the spec's bilinear
    quadrilateral, full integration), ``"CPE4I"`` (incompatible modes), ``"quad8"`` /
    ``"CPE8"``, ``"quad9"`` (quadratic cells on the same grid: midside nodes added,
    so the interface has twice the pairs).
    """
    if not isinstance(refine, (int, np.integer)) or refine < 1:
        raise InputError(f"refine must be a positive integer, got {refine!r}")
    s = SANDWICH_2D
    steel = Material(s["E"], s["nu"], s["rho"])
    bottom = Body("bottom", _beam(0.0, refine, top=False, element=element), steel,
                  clamps=(Clamp("clamp"),), pressures=(Pressure("bolt", s["p_bolt"]),))
    top = Body("top", _beam(s["h"], refine, top=True, element=element), steel,
               clamps=(Clamp("clamp"),), pressures=(Pressure("bolt", s["p_bolt"]),))
    return Model(
        bodies=(bottom, top),
        interface=Interface("bottom", "interface", "top", "interface"),
        tip=Probe(sets=(("bottom", "tip"), ("top", "tip")), direction=(0.0, 1.0)),
        mu=s["mu"] if mu is None else mu,
        name=f"sandwich-2d (refine={refine})" if element == "quad"
        else f"sandwich-2d (refine={refine}, element={element})",
    )


#: parameters of sandwich-3d (docs/benchmarks.md; SI units)
SANDWICH_3D = dict(
    L=0.2032, h=0.00635, b=0.0254, contact_length=0.0508, E=200e9, nu=0.285, rho=6600.0,
    x_bolt=0.2032 - 0.0254, a_washer=0.0127, bolt_force=4450.0, mu=0.6,
    n_thick=4, n_coarse=30, n_fine=32, n_width=16,
)


def _beam_3d(y0, refine, top, element="hexahedron"):
    s = SANDWICH_3D
    L, h, b, lc, a = s["L"], s["h"], s["b"], s["contact_length"], s["a_washer"]
    xs = graded_axis((0.0, L - lc, s["n_coarse"] * refine), (L - lc, L, s["n_fine"] * refine))
    ys = np.linspace(y0, y0 + h, s["n_thick"] * refine + 1)
    zs = np.linspace(0.0, b, s["n_width"] * refine + 1)
    cell_type, name = _element(element, ELEMENTS_3D)
    mesh = structured_mesh(xs, ys, zs, cell_type=cell_type)
    eps = 1e-9 * L
    xb0, xb1 = s["x_bolt"] - a / 2, s["x_bolt"] + a / 2
    zb0, zb1 = b / 2 - a / 2, b / 2 + a / 2
    y_if = y0 if top else y0 + h
    y_bolt = y0 + h if top else y0
    on = lambda y: (lambda p: np.abs(p[:, 1] - y) < eps)
    washer = lambda p: ((p[:, 0] >= xb0 - eps) & (p[:, 0] <= xb1 + eps)
                        & (p[:, 2] >= zb0 - eps) & (p[:, 2] <= zb1 + eps))
    facet_sets = {
        "interface": mesh.boundary_facets_where(
            lambda p: on(y_if)(p) & (p[:, 0] >= L - lc - eps)),
        "bolt": mesh.boundary_facets_where(lambda p: on(y_bolt)(p) & washer(p)),
        "outer": mesh.boundary_facets_where(on(y_bolt)),
        "end": mesh.boundary_facets_where(lambda p: np.abs(p[:, 0] - L) < eps),
    }
    node_sets = {"clamp": np.flatnonzero(np.abs(mesh.points[:, 0]) < eps),
                 "tip": np.flatnonzero(np.abs(mesh.points[:, 0] - L) < eps)}
    return dataclasses.replace(mesh, element=name).with_sets(node_sets=node_sets,
                                                             facet_sets=facet_sets)


def sandwich_3d(refine: int = 1, mu: float | None = None,
                element: str = "hexahedron") -> Model:
    """The sandwich-3d model (docs/benchmarks.md): 10,710 nodes and 561
    interface pairs at ``refine=1``; every hexahedron divided ``refine^3``.

    ``element`` (a key of ``ELEMENTS_3D``): ``"hexahedron"`` (default, trilinear, full
    integration), ``"C3D8I"`` (incompatible modes), ``"hexahedron20"`` / ``"C3D20"``,
    ``"hexahedron27"`` / ``"C3D27"`` (quadratic cells on the same grid).
    """
    if not isinstance(refine, (int, np.integer)) or refine < 1:
        raise InputError(f"refine must be a positive integer, got {refine!r}")
    s = SANDWICH_3D
    steel = Material(s["E"], s["nu"], s["rho"])
    p = s["bolt_force"] / s["a_washer"] ** 2
    bottom = Body("bottom", _beam_3d(0.0, refine, top=False, element=element), steel,
                  clamps=(Clamp("clamp"),), pressures=(Pressure("bolt", p),))
    top = Body("top", _beam_3d(s["h"], refine, top=True, element=element), steel,
               clamps=(Clamp("clamp"),), pressures=(Pressure("bolt", p),))
    return Model(
        bodies=(bottom, top),
        interface=Interface("bottom", "interface", "top", "interface"),
        tip=Probe(sets=(("bottom", "tip"), ("top", "tip")), direction=(0.0, 1.0, 0.0)),
        mu=s["mu"] if mu is None else mu,
        name=f"sandwich-3d (refine={refine})" if element == "hexahedron"
        else f"sandwich-3d (refine={refine}, element={element})",
    )
