r"""Element matrices of a whole mesh as batched numpy products, assembled straight into
qsma's DOF order.

scikit-fem supplies what it is good at: the elements (reference shape functions,
``Element.lbasis``), the quadrature rules and the DOF numbering of quadratic cells.
The iso-parametric map is evaluated here for batches of elements at once, from the
reference gradients of the geometry element:

.. math:: J_{ij} = \frac{\partial x_i}{\partial \xi_j} = \sum_g x_{g i}
          \frac{\partial \hat N_g}{\partial \xi_j}, \qquad
          \nabla N_a = J^{-T} \hat\nabla N_a, \qquad
          \mathrm{d}x_q = w_q\, |\det J(\xi_q)| ,

with the inverse written through the cofactors, ``J^{-1} = adj(J) / det J`` (as
scikit-fem's own mapping does). This replaces the evaluation of a scikit-fem
``CellBasis`` on every element (one Python call per basis function and Jacobian
entry, arrays of every basis function kept at once), the largest part of the
assembly of a 3D body. The element matrices

.. math:: K^e_{(a i)(b k)} = \sum_q \mathrm{d}x_q \left[\lambda\, g_{a i} g_{b k}
          + \mu \left( g_a \cdot g_b\, \delta_{ik} + g_{a k} g_{b i} \right)\right],
          \qquad M^e_{(a i)(b k)} = \rho \sum_q \mathrm{d}x_q N_a N_b\, \delta_{ik},

(``g_a = \nabla N_a`` at the quadrature point ``q``) are indexed node-major, local
DOF ``d a + i`` being global DOF ``d node(a) + i``; they are summed straight into the
``d x d`` blocks of a block-sparse matrix whose structure (one block per pair of
nodes sharing an element) is built once per mesh from the node graph
(:class:`BlockPattern`) and shared by the stiffness and the mass; scipy converts it to
CSR.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import skfem
from skfem.quadrature import get_quadrature

from .cache import per_mesh
from ..mesh.celltypes import CELL_TYPES
from .elements import fe_space

#: Elements per batch (bounds the temporary arrays: about 50 MB for hexahedron20).
BATCH = 4096


def reference_basis(element, X):
    """Values ``(nq, nb)`` and reference gradients ``(nq, nb, d)`` of the scalar
    scikit-fem ``element``'s shape functions at reference points ``X`` ``(d, nq)``."""
    pairs = [element.lbasis(X, a) for a in range(len(element.doflocs))]
    values = np.stack([phi for phi, _ in pairs], axis=1)
    grads = np.stack([dphi.T for _, dphi in pairs], axis=1)
    return values, grads


def jacobians(coords, dG):
    """``J[e, q, i, j] = sum_g coords[e, g, i] dG[q, g, j]``: the Jacobian of the
    iso-parametric map of each element ``e`` at each quadrature point ``q``."""
    return np.einsum("egi,qgj->eqij", coords, dG, optimize=True)


def inverse_and_determinant(J):
    """``(J^{-1}, det J)`` of a stack of 2x2 or 3x3 matrices ``J[..., i, j]`` by
    cofactors, ``J^{-1} = adj(J) / det J``."""
    d = J.shape[-1]
    if d == 2:
        det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
        adj = np.empty_like(J)
        adj[..., 0, 0] = J[..., 1, 1]
        adj[..., 0, 1] = -J[..., 0, 1]
        adj[..., 1, 0] = -J[..., 1, 0]
        adj[..., 1, 1] = J[..., 0, 0]
    elif d == 3:
        adj = np.empty_like(J)
        for i in range(3):
            i1, i2 = (i + 1) % 3, (i + 2) % 3
            for j in range(3):
                j1, j2 = (j + 1) % 3, (j + 2) % 3
                # adj[j, i] is the cofactor of J[i, j]
                adj[..., j, i] = J[..., i1, j1] * J[..., i2, j2] - J[..., i1, j2] * J[..., i2, j1]
        det = (J[..., 0, 0] * adj[..., 0, 0] + J[..., 0, 1] * adj[..., 1, 0]
               + J[..., 0, 2] * adj[..., 2, 0])
    else:
        raise ValueError(f"Jacobians of dimension {d} are not supported")
    return adj / det[..., None, None], det


@dataclass(frozen=True, eq=False)
class CellQuadrature:
    """What the batched element matrices of one single-type mesh need.

    Attributes
    ----------
    coords : ``(ne, ng, d)`` geometry nodes of every element (assembly coordinates)
    nodes : ``(ne, nb)`` qsma node of every scalar shape function of every element
    weights : ``(nq,)`` quadrature weights on the reference cell
    values : ``(nq, nb)`` shape function values at the quadrature points
    grads : ``(nq, nb, d)`` reference gradients of the shape functions
    geometry_grads : ``(nq, ng, d)`` reference gradients of the geometry functions
    """

    coords: np.ndarray
    nodes: np.ndarray
    weights: np.ndarray
    values: np.ndarray
    grads: np.ndarray
    geometry_grads: np.ndarray

    @property
    def n_elements(self):
        return self.nodes.shape[0]

    @property
    def dim(self):
        return self.coords.shape[2]

    def _mapped(self):
        """``(cut, J^-1, det J)`` per batch of :data:`BATCH` elements."""
        for start in range(0, self.n_elements, BATCH):
            cut = slice(start, min(start + BATCH, self.n_elements))
            yield (cut, *inverse_and_determinant(jacobians(self.coords[cut],
                                                           self.geometry_grads)))

    def mean_gradients(self):
        """``(ne, nb, d)``: the physical gradients of the shape functions averaged over
        the quadrature points of each element, ``mean_q dN_a/dx_i`` (computed once and
        kept): the gradient of a field averaged over an element is the field's nodal
        values times these, the element-centre stress of
        :func:`qsma.fe.assembly.stress_at_nodes` for every field written."""
        cached = self.__dict__.get("_mean_gradients")
        if cached is None:
            nq = len(self.weights)
            cached = np.concatenate([np.einsum("qaj,eqji->eai", self.grads, Jinv,
                                               optimize=True) / nq
                                     for _, Jinv, _ in self._mapped()])
            self.__dict__["_mean_gradients"] = cached
        return cached

    def batches(self):
        """``(cut, G, dx)`` per batch of :data:`BATCH` elements: the physical gradients
        ``G[e, q, a, i] = dN_a/dx_i`` and the weights ``dx[e, q] = w_q |det J|``."""
        for cut, Jinv, det in self._mapped():
            G = np.einsum("qaj,eqji->eqai", self.grads, Jinv, optimize=True)
            yield cut, G, np.abs(det) * self.weights

    def dx(self):
        """``(ne, nq)`` quadrature weights in physical space, ``w_q |det J|``."""
        return np.concatenate([np.abs(det) * self.weights for _, _, det in self._mapped()])


@per_mesh
def cell_quadrature(mesh, reduced=False) -> CellQuadrature:
    """The :class:`CellQuadrature` of a single-type qsma mesh (cached; meshes are
    immutable), with the quadrature order of :attr:`qsma.mesh.celltypes.CellType.skfem`
    (``reduced``: that of :attr:`~qsma.mesh.celltypes.CellType.reduced`)."""
    space = fe_space(mesh)
    m = space.mesh
    ct = CELL_TYPES[mesh.cell_type]
    intorder = ct.reduced[0] if reduced else ct.skfem[2]
    X, W = get_quadrature(space.element.refdom, intorder)
    values, grads = reference_basis(space.element, X)
    geometry = m.elem()
    _, geometry_grads = reference_basis(geometry, X)
    coords = m.doflocs.T[m.dofs.element_dofs.T]                  # (ne, ng, d)
    scalar_dofs = skfem.assembly.Dofs(m, space.element).element_dofs
    nodes = space.dof_node[scalar_dofs.T]                        # (ne, nb)
    return CellQuadrature(coords, nodes, W, values, grads, geometry_grads)


@dataclass(frozen=True, eq=False)
class BlockPattern:
    """Sparsity of a matrix of ``d x d`` node blocks, one block per pair of nodes that
    share an element (every entry of an element matrix, zeros included, as a
    coordinate-format assembly stores them).

    Attributes
    ----------
    indptr, indices : CSR structure of the node graph (sorted, unique columns)
    slot : ``(ne, nb, nb)`` position in ``indices`` of the node pair
        ``(nodes[e, a], nodes[e, b])``
    """

    indptr: np.ndarray
    indices: np.ndarray
    slot: np.ndarray

    @property
    def n_blocks(self):
        return len(self.indices)


def block_pattern(nodes, n_nodes) -> BlockPattern:
    """The :class:`BlockPattern` of elements with nodes ``nodes`` ``(ne, nb)``."""
    ne, nb = nodes.shape
    rows = np.repeat(nodes, nb, axis=1).ravel()
    cols = np.tile(nodes, (1, nb)).ravel()
    graph = sp.csr_matrix((np.ones(len(rows), dtype=np.float32), (rows, cols)),
                          shape=(n_nodes, n_nodes))
    graph.sum_duplicates()                                   # sorted, unique columns
    keys = (np.repeat(np.arange(n_nodes, dtype=np.int64), np.diff(graph.indptr)) * n_nodes
            + graph.indices)
    slot = np.searchsorted(keys, rows.astype(np.int64) * n_nodes + cols)
    if len(keys) < 2**31:            # held for the life of the cache: half the memory
        slot = slot.astype(np.int32)
    return BlockPattern(graph.indptr, graph.indices, slot.reshape(ne, nb, nb))


@per_mesh
def mesh_pattern(mesh) -> BlockPattern:
    """:func:`block_pattern` of a single-type qsma mesh (cached with the mesh)."""
    return block_pattern(cell_quadrature(mesh).nodes, mesh.n_nodes)


def sum_into_csr(component, pattern: BlockPattern, dim):
    """CSR matrix (DOF ``d node + i``) of element matrices given by ``component(i, k)``:
    the ``(ne, nb, nb)`` entries ``(a i, b k)`` of every element, or ``None`` where they
    are all zero. Entry ``(i, k)`` of the ``d x d`` block ``slot[e, a, b]`` of the
    pattern sums them (one ``np.bincount`` per component, explicit zeros kept); the
    block matrix is converted to CSR."""
    slot = pattern.slot.ravel()
    data = np.zeros((pattern.n_blocks, dim, dim))
    for i in range(dim):
        for k in range(dim):
            values = component(i, k)
            if values is not None:
                data[:, i, k] = np.bincount(slot, weights=values.ravel(),
                                            minlength=pattern.n_blocks)
    n = dim * (len(pattern.indptr) - 1)
    return sp.bsr_matrix((data, pattern.indices, pattern.indptr), shape=(n, n)).tocsr()


def elasticity_blocks(quad: CellQuadrature, lam, mu):
    """Element stiffness matrices ``(ne, nb d, nb d)`` of isotropic elasticity with Lame
    parameters ``lam``, ``mu`` (the formula of the module docstring)."""
    ne, nb, d = quad.n_elements, quad.nodes.shape[1], quad.dim
    out = np.empty((ne, nb * d, nb * d))
    for cut, G, dx in quad.batches():
        isotropic_blocks(G, dx, lam, mu, out=out[cut])
    return out


def isotropic_blocks(G, dx, lam, mu, out=None):
    """``(ne, nf d, nf d)`` element matrices of isotropic elasticity from the physical
    gradients ``G`` ``(ne, nq, nf, d)`` of ``nf`` functions and the weights ``dx``
    ``(ne, nq)``: with ``T_(a i)(b k) = sum_q dx g_ai g_bk`` (one batched product),
    ``K = lam T + mu T_(a k)(b i) + mu (sum_i T_(a i)(b i)) delta_ik``; written into
    ``out`` when given (no temporaries of the matrices' size but ``T``)."""
    ne, _, nf, d = G.shape
    B = G.reshape(ne, -1, nf * d)                                # (ne, nq, (a i))
    T = np.matmul(B.transpose(0, 2, 1) * dx[:, None, :], B)
    T5 = T.reshape(ne, nf, d, nf, d)
    gg = np.einsum("eaibi->eab", T5)                             # sum_q dx g_a . g_b
    if out is None:
        out = np.empty((ne, nf * d, nf * d))
    K = out.reshape(ne, nf, d, nf, d)
    np.multiply(T5, lam, out=K)
    T5 *= mu
    K += T5.transpose(0, 1, 4, 3, 2)
    gg *= mu
    for i in range(d):
        K[:, :, i, :, i] += gg
    return out


def scalar_mass_blocks(quad: CellQuadrature, rho):
    """``(ne, nb, nb)``: ``rho sum_q dx N_a N_b``, the same for every component."""
    return rho * np.einsum("qa,qb,eq->eab", quad.values, quad.values, quad.dx(),
                           optimize=True)


def stiffness(mesh, lam, mu, reduced=False) -> sp.csr_matrix:
    """Elasticity matrix of a single-type mesh in qsma DOF order (CSR); ``reduced``:
    on the cell type's reduced rule (:attr:`qsma.mesh.celltypes.CellType.reduced`)."""
    quad = cell_quadrature(mesh, True) if reduced else cell_quadrature(mesh)
    d, nb = mesh.dim, quad.nodes.shape[1]
    K = elasticity_blocks(quad, lam, mu).reshape(-1, nb, d, nb, d)
    return sum_into_csr(lambda i, k: K[:, :, i, :, k], mesh_pattern(mesh), d)


def mass(mesh, rho) -> sp.csr_matrix:
    """Consistent mass matrix of a single-type mesh in qsma DOF order (CSR)."""
    Mab = scalar_mass_blocks(cell_quadrature(mesh), rho)
    return sum_into_csr(lambda i, k: Mab if i == k else None, mesh_pattern(mesh),
                        mesh.dim)
