"""scikit-fem meshes, elements and the map from scikit-fem DOFs to qsma's node DOFs.

qsma numbers DOFs node-major over the mesh points, ``dim * node + component``.
scikit-fem numbers the DOFs of quadratic elements by mesh entity (vertices, then
edges, faces, interiors) with its own vertex numbering. :func:`fe_space` builds the
scikit-fem mesh and basis of a qsma mesh and the permutation ``perm`` with
``perm[skfem_dof] = qsma_dof``, found by matching, cell by cell, the location of
every scikit-fem DOF (``basis.doflocs``, the iso-parametric image of the reference
DOF location) with the coordinates of the cell's nodes. The match is checked: every
DOF must sit on one node of its own cell to round-off, and every node on one DOF.

Geometry: iso-parametric everywhere. Serendipity cells (quad8, hexahedron20) are
given to scikit-fem as 9- / 27-node Lagrange geometry whose extra face and body
centre points are evaluated from the serendipity map itself: the serendipity
functions lie in the (tri)biquadratic space, so interpolating them at the extra
nodes reproduces the serendipity geometry exactly. The extra points carry no DOF.

Coordinates: every scikit-fem mesh is built on coordinates relative to the lower
corner of the body's bounding box, so that assembly does not depend on where the
model sits in space (scikit-fem's inverse iso-parametric map, used by facet bases, iterates to
an absolute tolerance of 1e-12 and fails for models metres away from the origin).
Stiffness, mass and loads are invariant under translation; outputs keep the user's
coordinates because no qsma output is taken from the scikit-fem mesh.
"""
from __future__ import annotations

from dataclasses import dataclass
import functools

import numpy as np
import skfem

from .._infra.deprecation import forward
from ..errors import InputError
from ..mesh.celltypes import CELL_TYPES
from .cache import per_mesh

def local_origin(points: np.ndarray) -> np.ndarray:
    """Lower corner of the bounding box of ``points``: the origin of the assembly
    coordinates. Local coordinates then lie in ``[0, size]``; a body whose box already
    starts at the origin is assembled exactly as before (bit for bit), and for a
    translated body ``x - origin`` is computed without rounding (Sterbenz: the two
    numbers are within a factor 2 of each other) wherever ``|x| >= size``."""
    return points.min(axis=0) if len(points) else np.zeros(points.shape[1])


def lagrange_geometry(points: np.ndarray, cells: np.ndarray, cell_type: str):
    """Points and cells of the quadratic Lagrange geometry of serendipity cells.

    quad8 -> quad9: centre ``x_c = -1/4 sum(corners) + 1/2 sum(midsides)`` (the 8-node
    serendipity map at xi = eta = 0). hexahedron20 -> hexahedron27: face centre
    ``-1/4 sum(face corners) + 1/2 sum(face midsides)`` and body centre
    ``-1/4 sum(corners) + 1/4 sum(edge midsides)`` (the 20-node map at the face and
    body centres). Other cell types (no ``skfem_geometry`` of their own) are returned
    unchanged.
    """
    if CELL_TYPES[cell_type].skfem_geometry is None:
        return points, cells
    if cell_type == "quad8":
        extra = [-0.25 * points[cells[:, :4]].sum(1) + 0.5 * points[cells[:, 4:8]].sum(1)]
    elif cell_type == "hexahedron20":
        faces = CELL_TYPES["hexahedron20"].facets
        # hexahedron27 face-centre order 20..25: x-, x+, y-, y+, z-, z+ (VTK); our
        # hexahedron20 faces are z-, z+, y-, x+, y+, x-
        order = [5, 3, 2, 4, 0, 1]
        extra = [-0.25 * points[cells[:, list(faces[k][:4])]].sum(1)
                 + 0.5 * points[cells[:, list(faces[k][4:])]].sum(1) for k in order]
        extra.append(-0.25 * points[cells[:, :8]].sum(1) + 0.25 * points[cells[:, 8:20]].sum(1))
    else:
        raise NotImplementedError(f"no rule for the Lagrange geometry of {cell_type} cells")
    n = len(points)
    new = np.concatenate(extra)
    idx = n + np.arange(len(new)).reshape(len(extra), len(cells)).T
    return np.vstack([points, new]), np.hstack([cells, idx])


def build_skfem_mesh(points: np.ndarray, cells: np.ndarray, cell_type: str):
    """The scikit-fem mesh of cells ``cells`` (meshio order) on ``points``."""
    ct = CELL_TYPES[cell_type]
    cls = getattr(skfem, ct.skfem[0])
    points, cells = lagrange_geometry(points, cells, cell_type)
    geometry = CELL_TYPES[ct.skfem_geometry or cell_type]
    if geometry.skfem_nodes is not None:
        cells = cells[:, list(geometry.skfem_nodes)]
    try:
        return cls(np.ascontiguousarray(points.T), np.ascontiguousarray(cells.T),
                   validate=True, sort_t=False)
    except Exception as exc:  # scikit-fem raises ValueError / AssertionError
        raise InputError(f"invalid {cell_type} mesh: {exc}") from exc


@dataclass(frozen=True, eq=False)
class FESpace:
    """scikit-fem mesh and element of a qsma mesh, with the DOF permutation.

    Attributes
    ----------
    mesh : scikit-fem mesh on coordinates relative to ``origin``
    element : scalar scikit-fem element
    perm : ``perm[skfem_dof] = dim * node + component``; ``None`` when identical
    vertex_node : qsma node of each scikit-fem vertex
    origin : the assembly origin in the user's coordinates
    dof_node : qsma node of each scalar scikit-fem DOF
    intorder : quadrature order (:attr:`qsma.mesh.celltypes.CellType.skfem`)
    """

    mesh: object
    element: object
    perm: np.ndarray | None
    vertex_node: np.ndarray
    origin: np.ndarray
    dof_node: np.ndarray
    intorder: int

    @functools.cached_property
    def basis(self):
        """Vector :class:`skfem.Basis` on every element (built when first asked for:
        the matrices are assembled without it, :mod:`qsma.fe.batched`)."""
        return skfem.Basis(self.mesh, skfem.ElementVector(self.element),
                           intorder=self.intorder)

    def to_qsma_matrix(self, A, n_dofs):
        """``P A P^T``: a scikit-fem matrix renumbered to qsma DOFs (CSR)."""
        import scipy.sparse as sp
        A = A.tocoo()
        if self.perm is None:
            return sp.csr_matrix(A)
        return sp.csr_matrix((A.data, (self.perm[A.row], self.perm[A.col])),
                             shape=(n_dofs, n_dofs))

    def to_qsma_vector(self, f, n_dofs):
        if self.perm is None:
            return np.asarray(f, dtype=float)
        out = np.zeros(n_dofs)
        out[self.perm] = f
        return out

    def from_qsma_vector(self, u):
        """A qsma DOF vector in scikit-fem's numbering."""
        return np.asarray(u) if self.perm is None else np.asarray(u)[self.perm]


def _scalar_dof_nodes(basis, cells, points, tol):
    """qsma node of every scalar scikit-fem DOF, matched by coordinates cell by cell."""
    ed = basis.element_dofs                               # (nb, ncells)
    node_of = np.full(basis.N, -1, dtype=np.int64)
    chunk = 2048
    for s in range(0, cells.shape[0], chunk):
        c = cells[s:s + chunk]
        locs = basis.doflocs[:, ed[:, s:s + chunk]].transpose(2, 1, 0)   # (nc, nb, dim)
        xs = points[c]                                                    # (nc, nn, dim)
        d = np.linalg.norm(locs[:, :, None, :] - xs[:, None, :, :], axis=-1)
        k = d.argmin(axis=2)
        if np.take_along_axis(d, k[:, :, None], 2).max(initial=0.0) > tol:
            raise RuntimeError("scikit-fem DOF locations do not match the cell nodes")
        nodes = np.take_along_axis(c, k, axis=1)                          # (nc, nb)
        dofs = ed[:, s:s + chunk].T
        prev = node_of[dofs]
        if np.any((prev >= 0) & (prev != nodes)):
            raise RuntimeError("a scikit-fem DOF matches different nodes in two cells")
        node_of[dofs] = nodes
    if np.any(node_of < 0) or len(np.unique(node_of)) != len(node_of):
        raise RuntimeError("scikit-fem DOFs and mesh nodes are not one to one")
    return node_of


def _check_vector_numbering(basis, n_scalar, dim):
    """Vector DOF ``dim * s + c`` must be component ``c`` of scalar DOF ``s``: the
    vector field with those DOFs set to one must be the constant unit vector e_c."""
    if basis.N != dim * n_scalar:
        raise RuntimeError("unexpected scikit-fem vector DOF count")
    for c in range(dim):
        u = np.zeros(basis.N)
        u[c::dim] = 1.0
        val = np.asarray(basis.interpolate(u))             # (dim, ncells, nqp)
        target = np.eye(dim)[c][:, None, None]
        if np.abs(val - target).max() > 1e-10:
            raise RuntimeError("unexpected scikit-fem vector DOF ordering")


@per_mesh
def fe_space(mesh) -> FESpace:
    """The :class:`FESpace` of qsma mesh ``mesh`` (cached; meshes are immutable). One
    cell type: a mixed mesh has one space per block (:meth:`Mesh.block_meshes`)."""
    if mesh.is_mixed:
        raise ValueError("fe_space needs a single-type mesh; assemble a mixed mesh block "
                         "by block (Mesh.block_meshes)")
    ct = mesh.cell_type
    _, elem_name, intorder = CELL_TYPES[ct].skfem
    elem_cls = getattr(skfem, elem_name)
    origin = local_origin(mesh.points)
    points = mesh.points - origin
    m = build_skfem_mesh(points, mesh.cells, ct)
    elem = elem_cls()
    dim, n = mesh.dim, mesh.n_nodes
    # the vector numbering dim * scalar DOF + component, checked on one element
    probe = skfem.Basis(m, skfem.ElementVector(elem), intorder=1, elements=np.array([0]),
                        disable_doflocs=True)
    if CELL_TYPES[ct].is_linear:
        expected = dim * np.arange(n)[None, :] + np.arange(dim)[:, None]
        if not np.array_equal(probe.nodal_dofs, expected):
            raise RuntimeError("unexpected scikit-fem DOF ordering")  # guards our convention
        return FESpace(m, elem, None, np.arange(m.nvertices), origin, np.arange(n),
                       intorder)
    span = float(np.linalg.norm(np.ptp(points, axis=0))) if n else 1.0
    sbasis = skfem.Basis(m, elem, intorder=1)
    node_of = _scalar_dof_nodes(sbasis, mesh.cells, points, 1e-9 * span)
    _check_vector_numbering(probe, sbasis.N, dim)
    perm = np.empty(probe.N, dtype=np.int64)
    perm[dim * np.arange(sbasis.N)[:, None] + np.arange(dim)] = \
        dim * node_of[:, None] + np.arange(dim)
    return FESpace(m, elem, perm, node_of[:m.nvertices], origin, node_of, intorder)


def block_dofs(nodes: np.ndarray, dim: int) -> np.ndarray:
    """Mesh DOFs of the DOFs of a cell block (:meth:`qsma.mesh.Mesh.block_meshes`):
    block DOF ``dim * i + c`` is mesh DOF ``dim * nodes[i] + c``."""
    return (dim * np.asarray(nodes, dtype=np.int64)[:, None] + np.arange(dim)).ravel()


def scatter_matrix(A, dofs: np.ndarray, n_dofs: int):
    """``P A P^T`` for a matrix on block DOFs, ``dofs`` their mesh DOFs (CSR, n_dofs^2)."""
    import scipy.sparse as sp
    A = A.tocoo()
    return sp.csr_matrix((A.data, (dofs[A.row], dofs[A.col])), shape=(n_dofs, n_dofs))


# The table of scikit-fem elements became the ``skfem`` of each cell type record
# (:mod:`qsma.mesh.celltypes`); the old name keeps working for one release, with a
# DeprecationWarning.
forward(__name__, names={"SKFEM_ELEMENTS": "qsma.mesh._legacy"})
