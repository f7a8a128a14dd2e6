"""Geometric sanity of a mesh: inverted, degenerate and self-intersecting cells, nodes
defined twice at one point, nodes no cell uses.

:func:`validate_mesh` runs on every mesh read from a file (with the file's node and
element ids in its messages) and can be called on any :class:`~qsma.mesh.mesh.Mesh`.

The cell test is the *scaled Jacobian* of the isoparametric map
:math:`x(\\xi) = \\sum_a N_a(\\xi) x_a`,

.. math::

    q(\\xi) = \\frac{\\det J(\\xi)}{\\prod_k \\lVert J_{:,k}(\\xi) \\rVert},
    \\qquad J = \\frac{\\partial x}{\\partial \\xi},

evaluated at the corners and the other nodes of the reference cell and at its Gauss
points. :math:`q` is 1 for a right-angled cell of any aspect ratio and size, 0 for a cell
collapsed at that point, and negative where the map folds over. A cell is refused when
:math:`q \\le` :data:`DEGENERATE_SCALED_JACOBIAN` at any of these points: *inverted* when
it is negative at every point (nodes in clockwise order), *self-intersecting* (a bow-tie)
when its sign changes, *degenerate* otherwise. A cell with :math:`q <`
:data:`POOR_SCALED_JACOBIAN` somewhere is accepted with a :class:`MeshQualityWarning`.
"""
from __future__ import annotations

import itertools
import warnings
from functools import lru_cache

import numpy as np
from scipy.sparse import csr_matrix
from scipy.spatial import cKDTree

from ..errors import InputError, MeshFileError
from .celltypes import CELL_TYPES, reference_nodes
from .mesh import Mesh

__all__ = ["validate_mesh", "scaled_jacobians", "MeshQualityWarning",
           "DEGENERATE_SCALED_JACOBIAN", "POOR_SCALED_JACOBIAN", "COINCIDENT_NODES"]

#: A cell whose scaled Jacobian is at most this at a corner, node or Gauss point is
#: refused. q = sin of the angle between the cell's edge directions there (2D), so 1e-6
#: means an angle of 1e-6 rad: no mesher makes one, and the metric J^T J of such a cell
#: has a condition number of about 4 / q^2 = 4e12, beyond what double precision solves
#: to a useful accuracy. Valid but badly shaped cells (q = 0.01, an angle of 0.6
#: degrees) still pass.
DEGENERATE_SCALED_JACOBIAN = 1e-6

#: Below this scaled Jacobian (an angle of 0.57 degrees between edges) a cell is accepted
#: with a MeshQualityWarning. The meshes we ship and test have q >= 0.38 (Gmsh tetrahedra
#: of tests/data/gmsh_box_v41.msh; triangles 0.69, the sandwich quads 1.0); a node of
#: the example sandwich-2d-top.msh moved 0.3 m off the free surface by one damaged digit
#: gives q = 0.0026 and no other sign of damage.
POOR_SCALED_JACOBIAN = 0.01

#: Two nodes coincide when they are closer than this times the diagonal of the mesh's
#: bounding box (and than 1 % of the shortest distance from a cell's first corner to its
#: other corners). Gmsh writes 16 significant digits and the .inp files we have seen 10
#: to 14 (tests/data/gmsh_rect.inp: 14), so round-off leaves nodes meant to be one node
#: at most about 1e-10 of the model size apart, while nodes meant to be distinct are an
#: element size apart (1e-4 of the model size already means 10,000 elements across).
COINCIDENT_NODES = 1e-8


class MeshQualityWarning(UserWarning):
    """A mesh has valid but very badly shaped cells (see ``POOR_SCALED_JACOBIAN``)."""


#: Gauss points of the reference cells: 2 (linear) or 3 (quadratic) points per direction
#: on [-1, 1]; triangle 3 points (1/6, 1/6), (2/3, 1/6), (1/6, 2/3) and tetrahedron
#: 4 points (a, a, a), (b, a, a), ... with a = (5 - sqrt 5) / 20, b = (5 + 3 sqrt 5) / 20
#: (degree-2 rules, Zienkiewicz & Taylor, The Finite Element Method, vol. 1, table 6.3/6.4)
_A, _B = (5 - 5 ** 0.5) / 20, (5 + 3 * 5 ** 0.5) / 20
_SIMPLEX_POINTS = {2: [(1 / 6, 1 / 6), (2 / 3, 1 / 6), (1 / 6, 2 / 3)],
                   3: [(_A, _A, _A), (_B, _A, _A), (_A, _B, _A), (_A, _A, _B)]}


@lru_cache(maxsize=None)
def _reference(cell_type: str):
    """Reference node coordinates (n, d) and shape-function gradients at the check
    points (p, n, d) of a cell type, or None for a type without a table here."""
    ct = CELL_TYPES.get(cell_type)
    if ct is None:
        return None
    nodes, exps = reference_nodes(cell_type), np.array(ct.basis)
    d = nodes.shape[1]
    if ct.linear in ("triangle", "tetra"):
        gauss = np.array(_SIMPLEX_POINTS[d])
    else:
        g = [-3 ** -0.5, 3 ** -0.5] if ct.is_linear else [-0.6 ** 0.5, 0.0, 0.6 ** 0.5]
        gauss = np.array(list(itertools.product(g, repeat=d)))
    points = np.vstack([nodes, gauss])
    # N_a(x) = sum_m C[m, a] x^e_m with V C = I, V[a, m] = nodes[a]^e_m
    vander = np.prod(nodes[:, None, :] ** exps[None, :, :], axis=2)
    coeffs = np.linalg.solve(vander, np.eye(len(nodes)))
    grads = np.empty((len(points), len(nodes), d))
    for k in range(d):
        lowered = exps.copy()
        lowered[:, k] = np.maximum(exps[:, k] - 1, 0)
        dmono = exps[:, k] * np.prod(points[:, None, :] ** lowered[None, :, :], axis=2)
        grads[:, :, k] = dmono @ coeffs
    return nodes, grads


def scaled_jacobians(mesh: Mesh) -> np.ndarray | None:
    """Scaled Jacobian ``q`` of every cell at its reference nodes and Gauss points.

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    (n_cells, n_points) float array or None
        :math:`q = \\det J / \\prod_k \\lVert J_{:,k} \\rVert` (see the module docstring);
        the first columns are the cell's nodes in meshio order, then the Gauss points.
        None for a cell type this module has no reference cell for.
    """
    ref = _reference(mesh.cell_type)
    if ref is None:
        return None
    _, grads = ref
    nc = CELL_TYPES[mesh.cell_type].corners
    out = np.empty((len(mesh.cells), grads.shape[0]))
    for start in range(0, len(mesh.cells), _CHUNK):
        x = mesh.points[mesh.cells[start:start + _CHUNK]]              # (e, n, d)
        with np.errstate(over="ignore", invalid="ignore"):
            # q is invariant to translation and scaling: each cell is moved to its first
            # node and scaled by its largest coordinate extent (no overflow, any units)
            corners = x[:, :nc]
            size = np.max(corners.max(axis=1) - corners.min(axis=1), axis=1)
            x = (x - x[:, :1]) / np.where(size > 0, size, 1.0)[:, None, None]
        jac = np.tensordot(x, grads, axes=([1], [1]))                  # (e, d, p, k) by BLAS
        jac = np.moveaxis(jac, 2, 1)                                   # (e, p, d, k)
        norms = np.sqrt((jac * jac).sum(axis=2))                       # column norms
        q = _det(jac) / np.prod(np.maximum(norms, 1e-12), axis=2)      # cells of size ~1
        out[start:start + _CHUNK] = np.where(np.isfinite(q), q, 0.0)
    return out


#: cells per block in scaled_jacobians (bounds the memory: 16 points x 9 doubles each)
_CHUNK = 20000


def _det(a: np.ndarray) -> np.ndarray:
    """Determinants of stacked 2 x 2 or 3 x 3 matrices (cofactor expansion)."""
    if a.shape[-1] == 2:
        return a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] * a[..., 1, 0]
    return (a[..., 0, 0] * (a[..., 1, 1] * a[..., 2, 2] - a[..., 1, 2] * a[..., 2, 1])
            - a[..., 0, 1] * (a[..., 1, 0] * a[..., 2, 2] - a[..., 1, 2] * a[..., 2, 0])
            + a[..., 0, 2] * (a[..., 1, 0] * a[..., 2, 1] - a[..., 1, 1] * a[..., 2, 0]))


# --------------------------------------------------------------------------------------
# the checks

def validate_mesh(mesh: Mesh, *, source: str | None = None, node_ids=None,
                  cell_ids=None) -> None:
    """Refuse a mesh with bad cells, nodes defined twice or nodes no cell uses.

    Parameters
    ----------
    mesh : Mesh
    source : str, optional
        The file the mesh was read from; errors are then :class:`MeshFileError` and
        begin with it.
    node_ids, cell_ids : int arrays, optional
        The file's ids of the nodes and cells (default: index + 1), for the messages.

    Raises
    ------
    InputError (MeshFileError when ``source`` is given)
        A cell inverted, self-intersecting or degenerate (see the module docstring);
        two nodes at one point (closer than :data:`COINCIDENT_NODES` times the mesh
        size) that no cell joins; a node that no cell uses. The message names the ids
        and the fix.

    Notes
    -----
    Nodes no cell uses are refused rather than warned about: every node of a mesh gets
    degrees of freedom in the assembly, and one without a cell has neither stiffness nor
    mass, so the stiffness matrix is singular (with one such node added to
    the example ``sandwich-2d-bottom.inp``, ``qsma run`` stopped with an internal error in
    the assembly). Dropping them silently would renumber the nodes and could empty a
    node set that names them.
    """
    where = f"{source}: " if source else ""
    error = MeshFileError if source else InputError
    node_ids = np.arange(1, mesh.n_nodes + 1) if node_ids is None else np.asarray(node_ids)
    cell_ids = np.arange(1, mesh.n_cells + 1) if cell_ids is None else np.asarray(cell_ids)
    start = 0
    for view in _block_views(mesh):
        _check_cells(view, where, error, cell_ids[start:start + len(view.cells)], node_ids)
        start += len(view.cells)
    _check_coincident(mesh, where, error, node_ids)
    used = np.zeros(mesh.n_nodes, dtype=bool)
    for b in mesh.cell_blocks:
        used[b.cells.ravel()] = True
    if not used.all():
        unused = node_ids[~used]
        raise error(f"{where}{unused.size} node(s) are used by no element, e.g. node(s) "
                    f"{', '.join(map(str, unused[:5]))}; such a node has no stiffness and no "
                    f"mass (a singular model): delete these nodes from the mesh (reference "
                    f"points and construction nodes belong in another file)")


def _block_views(mesh: Mesh) -> list:
    """Single-type meshes on all of ``mesh``'s nodes, one per cell block."""
    if not mesh.is_mixed:
        return [mesh]
    return [Mesh(mesh.points, b.cells, b.cell_type) for b in mesh.cell_blocks]


def _check_cells(mesh, where, error, cell_ids, node_ids):
    q = scaled_jacobians(mesh)
    if q is None or q.size == 0:
        return
    worst = q.min(axis=1)
    bad = np.flatnonzero(worst <= DEGENERATE_SCALED_JACOBIAN)
    if not bad.size:
        poor = np.flatnonzero(worst < POOR_SCALED_JACOBIAN)
        if poor.size:
            e = poor[np.argmin(worst[poor])]
            warnings.warn(f"{where}{poor.size} {mesh.cell_type} element(s) are very badly "
                          f"shaped (scaled Jacobian below {POOR_SCALED_JACOBIAN:g}, an angle "
                          f"under 0.6 degrees), the worst element {cell_ids[e]} (nodes "
                          f"{', '.join(map(str, node_ids[mesh.cells[e]]))}) with "
                          f"{worst[e]:.3g}; check its node coordinates: a damaged number "
                          f"looks like this", MeshQualityWarning, stacklevel=3)
        return
    e = bad[0]
    row = q[e]
    nodes = ", ".join(map(str, node_ids[mesh.cells[e]]))
    if len(q) > 1 and (q < 0).all():
        raise error(f"{where}every one of the {len(q)} {mesh.cell_type} elements is inverted "
                    f"(negative Jacobian): the mesh is mirrored, e.g. a Gmsh surface whose "
                    f"normal points along -z; reverse the element orientation before saving "
                    f"(Gmsh: gmsh.model.mesh.reverse(), or reverse the surface) or list every "
                    f"element's nodes in the other order")
    if (row < 0).all():
        what = ("is inverted (negative Jacobian everywhere: its nodes are in clockwise order "
                "or the wrong way round)")
        fix = "list its nodes in the other orientation (counter-clockwise seen from outside)"
    elif (row < 0).any() and (row > DEGENERATE_SCALED_JACOBIAN).any():
        what = (f"is self-intersecting (its Jacobian changes sign: scaled Jacobian from "
                f"{row.min():.3g} to {row.max():.3g}; a bow-tie or folded cell)")
        fix = "correct the order of its nodes or the node coordinates"
    else:
        what = (f"is degenerate (scaled Jacobian {row.min():.3g} at a corner or integration "
                f"point, at most {DEGENERATE_SCALED_JACOBIAN:g}: collapsed edges or nodes "
                f"on one line or plane)")
        fix = "remesh it or correct its node coordinates"
    raise error(f"{where}{mesh.cell_type} element {cell_ids[e]} (nodes {nodes}) {what}; "
                f"{fix}. {bad.size} of {len(q)} elements fail this check")


def _check_coincident(mesh, where, error, node_ids):
    """Pairs of distinct nodes at one point that no cell joins."""
    points = mesh.points
    if mesh.n_nodes < 2:
        return
    with np.errstate(over="ignore", invalid="ignore"):     # absurd coordinates: inf, fine
        diagonal = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
        spans = []
        for b in mesh.cell_blocks:
            nc = CELL_TYPES[b.cell_type].corners
            spans.append(np.linalg.norm(points[b.cells[:, 1:nc]] - points[b.cells[:, :1]],
                                        axis=2).ravel())          # corner 0 to the others
        spans = np.concatenate(spans)
    shortest = spans[spans > 0].min(initial=diagonal)
    tol = min(COINCIDENT_NODES * diagonal, 0.01 * shortest)
    pairs = cKDTree(points).query_pairs(tol, output_type="ndarray")
    if not len(pairs):
        return
    rows = np.concatenate([np.repeat(np.arange(len(b.cells)), b.cells.shape[1])
                           + sum(len(c.cells) for c in mesh.cell_blocks[:k])
                           for k, b in enumerate(mesh.cell_blocks)])
    cols = np.concatenate([b.cells.ravel() for b in mesh.cell_blocks])
    incidence = csr_matrix((np.ones(len(cols)), (rows, cols)),
                           shape=(mesh.n_cells, mesh.n_nodes)).T.tocsr()
    joined = np.asarray(incidence[pairs[:, 0]].multiply(incidence[pairs[:, 1]])
                        .sum(axis=1)).ravel() > 0
    apart = pairs[~joined]
    if not len(apart):
        return
    a, b = apart[0]
    raise error(f"{where}nodes {node_ids[a]} and {node_ids[b]} are at the same point "
                f"{points[a].tolist()} (closer than {tol:.3g}) but no element joins them: "
                f"{len(apart)} such pair(s); the mesh falls apart there. Merge the duplicate "
                f"nodes (Gmsh: Geometry.Tolerance and Coherence Mesh; Abaqus: Mesh > Edit > "
                f"Merge nodes) or remove the unused copies")
