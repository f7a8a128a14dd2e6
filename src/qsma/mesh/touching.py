"""Where two meshes touch: the boundary facets of each that lie on the other's boundary,
facing it, for a contact interface the input does not name by its facet sets (Abaqus'
general contact, a TOML interface with ``touching = true``).

A boundary facet of one mesh touches the other when its centroid lies inside a
boundary facet of the other (projected on that facet's plane), within
:data:`TOUCH_GAP` of the smaller facet size from it along its normal, and the two
outward normals oppose each other within :data:`TOUCH_ANGLE`. Facets only partly
over the other mesh (at the edge of a washer, around a hole) count when their centroid
does; the mortar coupling integrates the overlap itself. Surfaces apart by a clearance
(a bolt shank in its hole) do not touch: they stay open in a QSMA and need no pair.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .celltypes import TYPES
from .facets import facet_normals
from .mesh import Mesh, boundary_facets

#: Largest distance between touching facets, as a fraction of the smaller facet's size
#: (its longest edge): coincident surfaces written with few digits, and curved ones
#: meshed differently (gap h^2 / 8R: 0.02 h at R = 6 h), pass; a clearance does not.
TOUCH_GAP = 0.05
#: Largest angle (degrees) between one facet's outward normal and the reverse of the
#: other's: faceted curved surfaces meshed differently differ by a few degrees.
TOUCH_ANGLE = 30.0
#: Facets of the other mesh tried per facet: those with the nearest centroids.
_CANDIDATES = 16
#: Slack of the inside test, in barycentric coordinates (centroids on a facet's edge).
_INSIDE_SLACK = 1e-9


def touching_facets(a: Mesh, b: Mesh, gap: float = TOUCH_GAP,
                    angle: float = TOUCH_ANGLE) -> tuple:
    """``(facets of a, facets of b)``: the boundary facets (node index rows, outward
    oriented) of each mesh that touch the other (module docstring)."""
    fa, fb = boundary_facets(a), boundary_facets(b)
    ga, gb = _geometry(a, fa), _geometry(b, fb)
    return fa[_touches(ga, gb, gap, angle)], fb[_touches(gb, ga, gap, angle)]


def _geometry(mesh: Mesh, facets: np.ndarray) -> dict:
    """Corners, unit outward normal, centroid and size (longest edge) of each facet."""
    p = mesh.points[facets[:, :TYPES[mesh.facet_type].corners]]
    n = facet_normals(mesh, facets)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    edges = np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2)
    return {"p": p, "n": n, "c": p.mean(axis=1), "h": edges.max(axis=1)}


def _touches(g: dict, o: dict, gap: float, angle: float) -> np.ndarray:
    """Which facets of ``g`` touch a facet of ``o``."""
    n_f = len(g["c"])
    if n_f == 0 or len(o["c"]) == 0:
        return np.zeros(n_f, dtype=bool)
    k = min(_CANDIDATES, len(o["c"]))
    _, idx = cKDTree(o["c"]).query(g["c"], k=k)
    idx = np.asarray(idx).reshape(n_f, k)
    on = o["n"][idx]                                            # (n, k, dim)
    rel = g["c"][:, None, :] - o["c"][idx]
    distance = np.abs(np.einsum("nkj,nkj->nk", rel, on))
    tol = gap * np.minimum(g["h"][:, None], o["h"][idx])
    facing = np.einsum("nj,nkj->nk", g["n"], on) <= -np.cos(np.radians(angle))
    inside = _inside(g["c"], o["p"][idx])
    return np.any((distance <= tol) & facing & inside, axis=1)


def _inside(q: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """(n, k): whether point ``q[i]``, projected on facet ``poly[i, j]`` (a segment in
    2D, a polygon of corners in 3D, fanned into triangles), falls inside it."""
    q = q[:, None, :]
    if poly.shape[-1] == 2:                                     # segments
        t = poly[:, :, 1] - poly[:, :, 0]
        s = np.einsum("nkj,nkj->nk", q - poly[:, :, 0], t) / np.einsum("nkj,nkj->nk", t, t)
        return (s >= -_INSIDE_SLACK) & (s <= 1 + _INSIDE_SLACK)
    found = np.zeros(poly.shape[:2], dtype=bool)
    for j in range(1, poly.shape[2] - 1):                       # the fan from corner 0
        a, b, c = poly[:, :, 0], poly[:, :, j], poly[:, :, j + 1]
        v0, v1, v2 = b - a, c - a, q - a
        d00, d01, d11 = (np.einsum("nkj,nkj->nk", x, y) for x, y in
                         ((v0, v0), (v0, v1), (v1, v1)))
        d20, d21 = np.einsum("nkj,nkj->nk", v2, v0), np.einsum("nkj,nkj->nk", v2, v1)
        det = d00 * d11 - d01 * d01
        with np.errstate(divide="ignore", invalid="ignore"):
            v = (d11 * d20 - d01 * d21) / det
            w = (d00 * d21 - d01 * d20) / det
        found |= (v >= -_INSIDE_SLACK) & (w >= -_INSIDE_SLACK) & \
            (v + w <= 1 + _INSIDE_SLACK)
    return found
