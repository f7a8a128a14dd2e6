"""stack-2d: three cantilever plates bolted together near the tip (three bodies, two
interfaces, a friction coefficient per interface).

The bottom and top plates are those of sandwich-2d (docs/benchmarks.md); a third
plate of the same section lies between them and is meshed on its own (by default
with fewer elements along the contact zone, so both interfaces are non-matching and
use the mortar coupling). All three are clamped at x = 0; the bolt presses the outer
faces of the bottom and top plates over the bolt head width.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..model import Body, Clamp, Interface, Material, Model, Pressure, Probe
from ..mesh.generate import graded_axis, structured_mesh
from .sandwich import SANDWICH_2D

#: parameters of stack-2d (SI units); the plates, material and bolt of sandwich-2d.
#: ``n_fine_middle``: elements of the middle plate along the contact zone (the outer
#: plates have ``n_fine``); equal values make both interfaces node-to-node.
STACK_2D = dict(SANDWICH_2D, n_thick=4, n_fine_middle=48)

BODY_NAMES = ("bottom", "middle", "top")


def _plate(k, refine, n_fine, contact_length):
    """Plate ``k`` (0 bottom, 1 middle, 2 top) occupying ``k h <= y <= (k + 1) h``."""
    s = STACK_2D
    L, h = s["L"], s["h"]
    if contact_length >= L:
        xs = np.linspace(0.0, L, (s["n_coarse"] + s["n_fine"]) * refine + 1)
    else:
        xs = graded_axis((0.0, L - contact_length, s["n_coarse"] * refine),
                         (L - contact_length, L, n_fine * refine))
    mesh = structured_mesh(xs, np.linspace(k * h, (k + 1) * h, s["n_thick"] * refine + 1))
    eps = 1e-9 * L
    x0 = max(L - contact_length, 0.0)
    zone = lambda y: (lambda p: (np.abs(p[:, 1] - y) < eps) & (p[:, 0] >= x0 - eps)
                      & (p[:, 0] > eps))
    xb0, xb1 = s["x_bolt"] - s["w_bolt"] / 2, s["x_bolt"] + s["w_bolt"] / 2
    bolt = lambda y: (lambda p: (np.abs(p[:, 1] - y) < eps) & (p[:, 0] >= xb0 - eps)
                      & (p[:, 0] <= xb1 + eps))
    facet_sets = {"lower": mesh.boundary_facets_where(zone(k * h)),
                  "upper": mesh.boundary_facets_where(zone((k + 1) * h))}
    if k != 1:
        facet_sets["bolt"] = mesh.boundary_facets_where(bolt(0.0 if k == 0 else 3 * h))
    node_sets = {"clamp": np.flatnonzero(mesh.points[:, 0] < eps),
                 "tip": np.flatnonzero(np.abs(mesh.points[:, 0] - L) < eps)}
    return mesh.with_sets(node_sets=node_sets, facet_sets=facet_sets)


def stack_2d(refine: int = 1, mu=None, n_fine_middle: int | None = None,
             contact_length: float | None = None, materials=None) -> Model:
    """The stack-2d model: bottom, middle and top plates, interfaces
    ``bottom.upper / middle.lower`` and ``middle.upper / top.lower``.

    Parameters
    ----------
    refine : every element divided ``refine x refine``
    mu : friction coefficient of both interfaces (float) or of each
        ``(lower, upper)``; default that of sandwich-2d
    n_fine_middle : elements of the middle plate along the contact zone (before
        ``refine``); :data:`STACK_2D` by default (non-matching), ``STACK_2D["n_fine"]``
        gives matching meshes (node-to-node)
    contact_length : length of the contact zone from the tip; the plate length ``L``
        makes the interfaces run the whole plates (but for the clamped nodes at x = 0),
        then the three plates tied are one plate of thickness ``3 h``
    materials : three :class:`qsma.model.Material` (bottom, middle, top); default the
        steel of sandwich-2d for all
    """
    if not isinstance(refine, (int, np.integer)) or refine < 1:
        raise InputError(f"refine must be a positive integer, got {refine!r}")
    s = STACK_2D
    mu = s["mu"] if mu is None else mu
    mus = (mu, mu) if np.ndim(mu) == 0 else tuple(mu)
    if len(mus) != 2:
        raise InputError(f"mu must be one number or two (lower, upper), got {mu!r}")
    n_mid = s["n_fine_middle"] if n_fine_middle is None else n_fine_middle
    lc = s["contact_length"] if contact_length is None else float(contact_length)
    if not 0 < lc <= s["L"]:
        raise InputError(f"contact_length must lie in (0, {s['L']}], got {contact_length!r}")
    steel = Material(s["E"], s["nu"], s["rho"])
    mats = (steel,) * 3 if materials is None else tuple(materials)
    bodies = []
    for k, name in enumerate(BODY_NAMES):
        mesh = _plate(k, refine, n_mid if k == 1 else s["n_fine"], lc)
        pressures = (Pressure("bolt", s["p_bolt"]),) if k != 1 else ()
        bodies.append(Body(name, mesh, mats[k], clamps=(Clamp("clamp"),),
                           pressures=pressures))
    interfaces = (Interface("bottom", "upper", "middle", "lower", mu=mus[0]),
                  Interface("middle", "upper", "top", "lower", mu=mus[1]))
    return Model(bodies=tuple(bodies), interfaces=interfaces,
                 tip=Probe(sets=tuple((b, "tip") for b in BODY_NAMES), direction=(0.0, 1.0)),
                 mu=mus[0], name=f"stack-2d (refine={refine})")

