"""Geometry of boundary facets: outward normals scaled by their area, and the
tributary weights (area shares) of their nodes."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .celltypes import CELL_TYPES, TYPES, reference_nodes
from .mesh import Mesh, facet_index

__all__ = ["facet_normals", "facet_node_weights"]


def facet_normals(mesh: Mesh, facets: np.ndarray) -> np.ndarray:
    """Unit outward normals of boundary facets, scaled by their area (length in 2D).

    Computed from the corner nodes (the first nodes of each row): exact for
    straight / flat facets, the chord (flat) approximation of curved quadratic ones.
    """
    p = mesh.points[facets[:, :TYPES[mesh.facet_type].corners]]
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
    """Centroid of the cell that owns each facet: boundary facets through the mesh's
    cached facet index, any other facet (internal, or of no cell) by the lookup below."""
    index = facet_index(mesh)
    row = index.find(facets)
    if len(row) and (row >= 0).all():
        cells = index.cell[row]
        cent = np.concatenate([mesh.points[b.cells].mean(axis=1) for b in mesh.cell_blocks])
        return cent[cells]
    return _owner_centroids_by_lookup(mesh, facets)


def _owner_centroids_by_lookup(mesh, facets):
    """Centroid of a cell holding each facet (the last one listed for an internal facet)."""
    owner, cent = {}, []
    for b in mesh.cell_blocks:                      # mixed meshes: every cell block
        local, nc, start = CELL_TYPES[b.cell_type].facets, len(b.cells), len(cent)
        allf = np.sort(np.concatenate([b.cells[:, list(f)] for f in local]), axis=1)
        owner.update({tuple(k): start + c % nc for c, k in enumerate(allf.tolist())})
        cent.extend(mesh.points[b.cells].mean(axis=1))
    cent = np.asarray(cent)
    keys = [tuple(k) for k in np.sort(facets, axis=1).tolist()]
    missing = [k for k in keys if k not in owner]
    if missing:
        raise InputError(f"facet with nodes {list(missing[0])} belongs to no cell of the mesh")
    return cent[[owner[k] for k in keys]]


def _facet_quadrature(shape):
    """Points and weights on the reference facet: 4-point Gauss per direction; the
    triangle by the collapsed (Duffy) square, exact to degree 7."""
    g, w = np.polynomial.legendre.leggauss(4)
    if shape == "line":
        return g[:, None], w
    u, v = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    wq = np.outer(w, w).ravel()
    if shape == "quad":
        return np.column_stack([u, v]), wq
    r = 0.5 * (1 + u)
    s = 0.5 * (1 - r) * (1 + v)
    return np.column_stack([r, s]), wq * 0.25 * (1 - r)


def _facet_shape_functions(facet_type):
    """Shape function values ``(n_qp, n_nodes)`` and reference gradients ``(n_qp,
    n_nodes, facet_dim)`` at the quadrature points, with the quadrature weights."""
    ft = TYPES[facet_type]
    nodes, exps, shape = reference_nodes(facet_type), np.asarray(ft.basis), ft.linear
    V = np.prod(nodes[:, None, :] ** exps[None, :, :], axis=2)          # (node, monomial)
    C = np.linalg.inv(V)                                                 # N = m(x) @ C
    x, w = _facet_quadrature(shape)
    mono = np.prod(x[:, None, :] ** exps[None, :, :], axis=2)
    grads = []
    for k in range(exps.shape[1]):
        e = exps.copy()
        coef = e[:, k].astype(float)
        e[:, k] = np.maximum(e[:, k] - 1, 0)
        grads.append((coef * np.prod(x[:, None, :] ** e[None, :, :], axis=2)) @ C)
    return mono @ C, np.stack(grads, axis=-1), w


def facet_node_weights(points: np.ndarray, facets: np.ndarray, facet_type: str):
    """Positive tributary weights (length in 2D, area in 3D) of the nodes of facets.

    Row-sum ("consistent") shares ``int N_a dA`` of quadratic facets are not all
    positive (quad8: -1/12 of the facet at each corner; triangle6: 0 at the corners),
    so they cannot serve as the area that turns a nodal contact force into a pressure.
    These weights are the diagonal (HRZ) lumping of the facet's mass matrix,

    .. math:: w_a = A \\, \\frac{\\int N_a^2 \\, dA}{\\sum_b \\int N_b^2 \\, dA},
              \\qquad A = \\int dA,

    positive for every facet type, summing to the facet area, and equal to the
    consistent shares wherever those are positive on straight / flat facets: line
    ``1/2, 1/2``; line3 ``1/6, 1/6, 2/3``; quad4 (parallelogram) ``1/4`` each; quad9
    ``1/36`` corners, ``1/9`` midsides, ``4/9`` centre; triangle ``1/3`` each. For
    quad8 they are ``3/76`` at the corners and ``4/19`` at the midsides (of the facet
    area, rectangles), for triangle6 ``1/19`` and ``16/57``. Curved facets are
    integrated iso-parametrically (4 Gauss points per direction).

    Returns
    -------
    (n_facets, nodes_per_facet) float array
    """
    N, dN, w = _facet_shape_functions(facet_type)
    x = points[np.asarray(facets, dtype=np.int64)]                     # (f, n, dim)
    tangents = np.einsum("qnk,fnd->fqdk", dN, x)                       # (f, q, dim, k)
    if tangents.shape[-1] == 1:
        jac = np.linalg.norm(tangents[..., 0], axis=-1)
    else:
        jac = np.linalg.norm(np.cross(tangents[..., 0], tangents[..., 1]), axis=-1)
    dA = jac * w                                                       # (f, q)
    area = dA.sum(axis=1)
    diag = np.einsum("fq,qn->fn", dA, N * N)
    return area[:, None] * diag / diag.sum(axis=1, keepdims=True)
