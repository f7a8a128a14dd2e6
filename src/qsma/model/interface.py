"""Contact interface: node pairs matched by coordinates, local pair frames."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from .mesh import Mesh, boundary_facets


@dataclass(frozen=True)
class Interface:
    """A node-to-node contact interface: facet set ``set1`` of ``body1`` against
    facet set ``set2`` of ``body2``. The pair normal points from body 1 into body 2.

    ``tol`` is the pairing tolerance (absolute, m); ``None`` takes 1e-6 times the
    interface's bounding-box diagonal.
    """

    body1: str
    set1: str
    body2: str
    set2: str
    tol: float | None = None


@dataclass(frozen=True, eq=False)
class Pairing:
    """Matched node pairs of an interface.

    Attributes
    ----------
    nodes1, nodes2 : (n_pairs,) node indices in body 1 and body 2
    x : (n_pairs, dim) pair coordinates (body 1)
    frames : (n_pairs, dim, dim) rows are the local axes, ``(t, n)`` in 2D and
        ``(t1, t2, n)`` in 3D, fixed in the undeformed configuration
    area : (n_pairs,) tributary area (length in 2D, per unit depth) of each pair
    """

    nodes1: np.ndarray
    nodes2: np.ndarray
    x: np.ndarray
    frames: np.ndarray
    area: np.ndarray

    @property
    def n_pairs(self):
        return len(self.nodes1)

    @property
    def normals(self):
        return self.frames[:, -1, :]


def pair_nodes(mesh1: Mesh, set1: str, mesh2: Mesh, set2: str, tol=None, names=("1", "2")):
    """Match the nodes of two facet sets by coordinates.

    Returns ``(nodes1, nodes2)`` sorted along the interface (lexicographic in the
    coordinates). Raises :class:`InputError` naming unmatched nodes and their
    distance to the nearest candidate.
    """
    n1, n2 = mesh1.nodes(set1), mesh2.nodes(set2)
    x1, x2 = mesh1.points[n1], mesh2.points[n2]
    if tol is None:
        span = np.ptp(np.vstack([x1, x2]), axis=0)
        tol = 1e-6 * max(float(np.linalg.norm(span)), 1e-300)
    dist12, j = cKDTree(x2).query(x1)
    dist21, i = cKDTree(x1).query(x2)
    bad1 = np.flatnonzero(dist12 > tol)
    bad2 = np.flatnonzero(dist21 > tol)
    if bad1.size or bad2.size:
        lines = [f"  body {names[0]} node {n1[k]} at {x1[k].tolist()}: nearest node of "
                 f"body {names[1]} set {set2!r} is {dist12[k]:.3e} away" for k in bad1[:10]]
        lines += [f"  body {names[1]} node {n2[k]} at {x2[k].tolist()}: nearest node of "
                  f"body {names[0]} set {set1!r} is {dist21[k]:.3e} away" for k in bad2[:10]]
        more = len(bad1) + len(bad2) - len(lines)
        raise InputError(
            f"interface {set1!r} / {set2!r}: {len(bad1) + len(bad2)} node(s) have no partner "
            f"within tol={tol:.3e} m (node-to-node contact needs matching meshes):\n"
            + "\n".join(lines) + (f"\n  ... and {more} more" if more > 0 else "")
            + "\nFix: mesh both sides with coincident nodes, or raise the pairing tolerance.")
    if len(np.unique(j)) != len(j):
        raise InputError(f"interface {set1!r} / {set2!r}: several nodes of body {names[0]} "
                         f"match the same node of body {names[1]}; duplicate nodes?")
    order = np.lexsort(x1.T[::-1])
    return n1[order], n2[j[order]]


def facet_normals(mesh: Mesh, facets: np.ndarray) -> np.ndarray:
    """Unit outward normals of boundary facets, scaled by their area (length in 2D).

    Computed from the corner nodes (the first ``FACET_CORNERS`` of each row): exact for
    straight / flat facets, the chord (flat) approximation of curved quadratic ones.
    """
    from .mesh import FACET_CORNERS
    p = mesh.points[facets[:, :FACET_CORNERS[mesh.facet_type]]]
    if mesh.dim == 2:
        t = p[:, 1] - p[:, 0]
        nrm = np.stack([t[:, 1], -t[:, 0]], axis=1)
    else:
        # polygon (triangle or quad): half the cross product of the diagonals / edges
        if p.shape[1] == 3:
            nrm = 0.5 * np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        else:
            nrm = 0.5 * np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    # orient outward: away from the centroid of the owning cell
    owner = _owner_centroids(mesh, facets)
    flip = np.einsum("ij,ij->i", nrm, p.mean(axis=1) - owner) < 0
    nrm[flip] *= -1
    return nrm


def _owner_centroids(mesh, facets):
    """Centroid of the cell that owns each facet."""
    from .mesh import CELL_FACETS
    local = CELL_FACETS[mesh.cell_type]
    nc = len(mesh.cells)
    allf = np.sort(np.concatenate([mesh.cells[:, list(f)] for f in local]), axis=1)
    owner = {tuple(k): c % nc for c, k in enumerate(allf.tolist())}
    cent = mesh.points[mesh.cells].mean(axis=1)
    keys = [tuple(k) for k in np.sort(facets, axis=1).tolist()]
    missing = [k for k in keys if k not in owner]
    if missing:
        raise InputError(f"facet with nodes {list(missing[0])} belongs to no cell of the mesh")
    return cent[[owner[k] for k in keys]]


def local_frames(normals: np.ndarray) -> np.ndarray:
    """Orthonormal frames with the unit normal last: ``(t, n)`` in 2D with t = n rotated
    by -90 degrees (n = +y gives t = +x); ``(t1, t2, n)`` in 3D with t1 the projection of
    +x (of +z when n is nearly along x) and t2 = t1 x n (n = +y gives t1 = +x, t2 = +z)."""
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    if n.shape[1] == 2:
        t = np.stack([n[:, 1], -n[:, 0]], axis=1)
        return np.stack([t, n], axis=1)
    ref = np.where(np.abs(n[:, :1]) > 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    t1 = ref - np.einsum("ij,ij->i", ref, n)[:, None] * n
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(t1, n)
    return np.stack([t1, t2, n], axis=1)


def make_pairing(model) -> Pairing:
    """Pair the interface nodes of ``model`` and build the local frames."""
    itf = model.interface
    b1, b2 = model.body(itf.body1), model.body(itf.body2)
    facets1 = b1.mesh.facets(itf.set1)
    b2.mesh.facets(itf.set2)
    nodes1, nodes2 = pair_nodes(b1.mesh, itf.set1, b2.mesh, itf.set2, itf.tol,
                                names=(b1.name, b2.name))
    _check_boundary(b1.mesh, facets1, b1.name, itf.set1)
    weighted = facet_normals(b1.mesh, facets1)          # outward normal x facet area
    nvf = facets1.shape[1]
    normal_sum = np.zeros((b1.mesh.n_nodes, b1.dim))
    np.add.at(normal_sum, facets1.ravel(), np.repeat(weighted / nvf, nvf, axis=0))
    area = np.zeros(b1.mesh.n_nodes)
    np.add.at(area, facets1.ravel(), np.repeat(np.linalg.norm(weighted, axis=1) / nvf, nvf))
    frames = local_frames(normal_sum[nodes1])
    return Pairing(nodes1, nodes2, b1.mesh.points[nodes1].copy(), frames, area[nodes1])


def _check_boundary(mesh, facets, body, name):
    bf = {tuple(sorted(f)) for f in boundary_facets(mesh).tolist()}
    inner = [f for f in facets.tolist() if tuple(sorted(f)) not in bf]
    if inner:
        raise InputError(f"body {body!r}: facet set {name!r} contains {len(inner)} facet(s) "
                         f"not on the boundary of this body, e.g. nodes {inner[0]}; is the "
                         f"interface set defined on the wrong body?")
