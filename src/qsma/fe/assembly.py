"""Assembly of one body with scikit-fem: K, M, pressure loads, free DOFs.

DOFs are node-major: DOF ``dim * node + component`` over the mesh points; scikit-fem's
own numbering (entity by entity for quadratic elements) is mapped to it by
:func:`qsma.fe.elements.fe_space`. The element formulation of a body (plane strain
or plane stress with unit thickness in 2D, full integration or incompatible modes) is
resolved from its mesh by :func:`qsma.fe.formulation.resolve_formulations` and
reported in :attr:`AssembledBody.formulation`. Assembly runs on coordinates relative
to the body's bounding-box corner, so results do not depend on where the model sits.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import skfem
from skfem.helpers import ddot, div, dot, sym_grad

from ..errors import InputError
from ..mesh.celltypes import TYPES
from ..mesh.mesh import Mesh, facet_index
from ..model.body import Body
from ..model.mass import point_mass_matrix
from ..model.spring import spring_matrix
from . import batched
from .elements import block_dofs, fe_space, scatter_matrix
from .formulation import Formulation, MixedFormulation, resolve_formulations


def skfem_mesh(mesh: Mesh):
    """The scikit-fem mesh of ``mesh``, on coordinates relative to the lower corner of its
    bounding box (:func:`qsma.fe.elements.local_origin`)."""
    return fe_space(mesh).mesh


def _basis(mesh: Mesh):
    """scikit-fem mesh and vector basis of ``mesh`` (cached in :func:`fe_space`)."""
    space = fe_space(mesh)
    return space.mesh, space.basis


def plane_lame(material, formulation: Formulation):
    """Lame parameters of the formulation: ``(lambda, mu)`` of the material in plane
    strain and 3D; in plane stress ``lambda* = 2 lambda mu / (lambda + 2 mu)``
    (sigma_zz = 0 eliminates eps_zz), i.e. ``E nu / (1 - nu^2)``."""
    lam, mu = material.lame
    if formulation.kinematics == "plane stress":
        lam = 2.0 * lam * mu / (lam + 2.0 * mu)
    return lam, mu


def _elasticity_form(lam, mu):
    """Isotropic elasticity, ``sigma : eps(v)`` with ``sigma = 2 mu eps + lam tr(eps) I``,
    written as ``lam div(u) div(v) + 2 mu eps(u) : eps(v)``: the same matrix as
    ``skfem.models.elasticity.linear_elasticity`` (1e-15, tests/test_fe.py); the
    reference of the batched assembly (:mod:`qsma.fe.batched`) in the tests."""
    @skfem.BilinearForm
    def form(u, v, w):
        return lam * div(u) * div(v) + 2.0 * mu * ddot(sym_grad(u), sym_grad(v))
    return form


def _mass_form(rho):
    """Consistent mass ``rho u . v`` (the reference of :func:`qsma.fe.batched.mass`)."""
    @skfem.BilinearForm
    def form(u, v, w):
        return rho * dot(u, v)
    return form


@dataclass(frozen=True, eq=False)
class AssembledBody:
    """Sparse operators of one body (all DOFs; Dirichlet DOFs listed in ``fixed``).

    ``loads`` maps a load pattern name to its full-length force vector; a displacement
    the clamps prescribe (``prescribed``: pattern name -> full-length displacement,
    nonzero only at Dirichlet DOFs) enters its pattern's load as the force it exerts
    on the free DOFs, ``-K[:, p] u_p``, and the recovered fields as itself.
    ``formulation`` says which element was computed (:attr:`Formulation.label`, e.g.
    ``"CPE4: plane strain (unit thickness), 4-node quadrilateral (bilinear), full
    integration, 2x2 Gauss"``); ``element`` is the :class:`Formulation` itself.
    """

    body: Body
    K: sp.csr_matrix
    M: sp.csr_matrix
    loads: dict
    fixed: np.ndarray
    free: np.ndarray
    element: Formulation | MixedFormulation | None = None
    prescribed: dict = None
    #: motions that ``K`` does not resist beside the rigid ones: the openings of the
    #: pretension sections that cut the body (columns; :mod:`qsma.fe.sections`), or None
    openings: np.ndarray = None

    @property
    def n_dofs(self):
        return self.K.shape[0]

    @property
    def formulation(self) -> str:
        return self.element.label if self.element is not None else ""


def stiffness_matrix(body: Body, formulation: Formulation | MixedFormulation | None = None
                     ) -> sp.csr_matrix:
    """Stiffness matrix of ``body`` in qsma DOF order for its formulation (mixed meshes:
    the sum of the blocks' matrices, each with its own formulation)."""
    form = resolve_formulations(body.mesh) if formulation is None else formulation
    if body.mesh.is_mixed:
        return _sum_over_blocks(body, lambda b, k: stiffness_matrix(b, form.parts[k]))
    lam, mu = plane_lame(body.material, form)
    if form.incompatible:
        from .incompatible import incompatible_stiffness
        return incompatible_stiffness(body.mesh, lam, mu)
    return batched.stiffness(body.mesh, lam, mu, getattr(form, "reduced", False))


def mass_matrix(body: Body) -> sp.csr_matrix:
    """Consistent mass matrix of ``body`` (the displacement interpolation of the cell
    type; incompatible modes carry no mass)."""
    if body.mesh.is_mixed:
        return _sum_over_blocks(body, lambda b, k: mass_matrix(b))
    return batched.mass(body.mesh, body.material.rho)


def assemble_body(body: Body) -> AssembledBody:
    """Assemble stiffness, consistent mass and the pressure load patterns of a body,
    with the formulation :func:`resolve_formulations` gives for its mesh."""
    form = resolve_formulations(body.mesh)
    K = stiffness_matrix(body, form)
    if body.springs:                        # grounded springs (qsma.model.spring)
        K = (K + spring_matrix(body)).tocsr()
    M = mass_matrix(body)
    if body.masses:                         # point masses (qsma.model.mass)
        M = (M + point_mass_matrix(body)).tocsr()
    loads = {name: body_load(body, name) for name in body.load_names()}
    fixed = body.clamped_dofs()
    free = np.setdiff1d(np.arange(body.n_dofs), fixed)
    prescribed = {}
    u_p = body.prescribed_displacement()
    if u_p is not None:                     # the preload's prescribed displacement
        prescribed["preload"] = u_p
        loads["preload"] = loads["preload"] - K @ u_p
    return AssembledBody(body, K, M, loads, fixed, free, form, prescribed)


def _block_bodies(body: Body):
    """``(body of one cell block, its mesh DOFs)`` per block of a mixed mesh."""
    return [(Body(body.name, m, body.material), block_dofs(nodes, body.dim))
            for m, nodes in body.mesh.block_meshes()]


def _sum_over_blocks(body: Body, matrix) -> sp.csr_matrix:
    """Mixed mesh: ``sum_b P_b A_b P_b^T`` of the block matrices ``matrix(body_b, b)``
    (one scikit-fem basis per cell type), renumbered to the mesh DOFs."""
    total = sp.csr_matrix((body.n_dofs, body.n_dofs))
    for k, (b, dofs) in enumerate(_block_bodies(body)):
        total = total + scatter_matrix(matrix(b, k), dofs, body.n_dofs)
    return total.tocsr()


def _facet_indices(m, facets: np.ndarray, what: str) -> np.ndarray:
    """Indices into ``m.facets`` of the facets given by scikit-fem vertex rows."""
    key = {tuple(k): i for i, k in enumerate(np.sort(m.facets.T, axis=1).tolist())}
    idx = [key.get(tuple(f)) for f in np.sort(facets, axis=1).tolist()]
    missing = [facets[i].tolist() for i, v in enumerate(idx) if v is None]
    if missing:
        raise InputError(f"{what}: facet with nodes {missing[0]} is not a facet of the mesh")
    return np.asarray(idx, dtype=np.int64)


def pressure_load(body: Body, facet_set: str, p: float) -> np.ndarray:
    """Consistent nodal forces of pressure ``p`` (positive into the body) on a facet set,
    ``f_a = -p int_Gamma N_a n dGamma`` (``n`` the outward unit normal), by Gauss
    quadrature on the iso-parametric facets. On quadratic facets these forces are not
    all positive (serendipity quad8 facets: corners get -1/12 of the resultant each).
    """
    rows = body.mesh.facets(facet_set)
    what = f"body {body.name!r} facet set {facet_set!r}"
    if body.mesh.is_mixed:
        return _mixed_pressure(body.mesh, rows, p, what)
    return _facet_pressure(body.mesh, rows, p, what)


def _facet_pressure(mesh: Mesh, rows: np.ndarray, p: float, what: str) -> np.ndarray:
    """:func:`pressure_load` on facets ``rows`` of a single-type mesh."""
    space = fe_space(mesh)
    n_dofs = mesh.dim * mesh.n_nodes
    ncorner = TYPES[mesh.facet_type].corners
    vertex_of = np.full(mesh.n_nodes, -1, dtype=np.int64)
    vertex_of[space.vertex_node] = np.arange(len(space.vertex_node))
    corners = vertex_of[rows[:, :ncorner]]
    if np.any(corners < 0):
        raise InputError(f"{what}: facet with nodes {rows[0].tolist()} is not a facet of "
                         f"the mesh")
    if len(rows) == 0:
        return np.zeros(n_dofs)
    facets = _facet_indices(space.mesh, corners, what)
    intorder = _facet_order(mesh.cell_type)
    fb = skfem.FacetBasis(space.mesh, skfem.ElementVector(space.element), facets=facets,
                          intorder=intorder)

    @skfem.LinearForm
    def traction(v, w):
        return -p * dot(w.n, v)          # w.n: outward unit normal
    return space.to_qsma_vector(skfem.asm(traction, fb), n_dofs)


def _mixed_pressure(mesh: Mesh, rows: np.ndarray, p: float, what: str) -> np.ndarray:
    """:func:`pressure_load` on a mixed mesh: each facet integrated with the basis of the
    cell block that owns it."""
    index = facet_index(mesh)
    found = index.find(rows)
    if np.any(found < 0):
        bad = rows[np.flatnonzero(found < 0)[0]].tolist()
        raise InputError(f"{what}: facet with nodes {bad} is not a boundary facet of the mesh")
    owner = index.cell[found]
    f = np.zeros(mesh.dim * mesh.n_nodes)
    start = 0
    for m, nodes in mesh.block_meshes():
        mine = (owner >= start) & (owner < start + len(m.cells))
        start += len(m.cells)
        if not mine.any():
            continue
        local = np.searchsorted(nodes, rows[mine])      # nodes: sorted mesh nodes of m
        f[block_dofs(nodes, mesh.dim)] += _facet_pressure(m, local, p, what)
    return f


def _facet_order(cell_type):
    """Facet quadrature: 2 Gauss points per direction for linear facets (exact), 3 for
    quadratic ones (exact for the shape functions times a straight facet's Jacobian)."""
    return 2 if cell_type in ("triangle", "quad", "tetra", "hexahedron") else 4


def body_load(body: Body, name: str) -> np.ndarray:
    """Sum of the pressure loads and nodal forces of pattern ``name``."""
    f = np.zeros(body.n_dofs)
    for pr in body.pressures:
        if pr.load == name:
            f += pressure_load(body, pr.set, pr.p)
    for nf in body.forces:
        if nf.load == name:
            nodes = np.unique(body.mesh.nodes(nf.set))
            f.reshape(-1, body.dim)[nodes] += np.asarray(nf.force)
    return f


def stress_at_nodes(body: Body, u: np.ndarray):
    """Nodal averages of the stress tensor from displacement ``u`` (full DOF vector).

    Returns ``(n_nodes, dim, dim)`` stresses and the von Mises stress per node (plane
    strain: sigma_zz = nu (sigma_xx + sigma_yy) included; plane stress: sigma_zz = 0).
    Incompatible-mode elements: the stress of the compatible (bilinear / trilinear)
    field; the incompatible modes' strain vanishes at the element centre, where the
    Gauss-point average is taken for parallelogram-shaped cells.
    """
    form = resolve_formulations(body.mesh)
    dim = body.dim
    # element-centre projection: average the Gauss point stresses per element, then to nodes
    acc = np.zeros((body.mesh.n_nodes, dim, dim))
    cnt = np.zeros(body.mesh.n_nodes)
    parts = form.parts if body.mesh.is_mixed else (form,)
    for (m, nodes), part in zip(body.mesh.block_meshes(), parts):
        u_block = u if nodes is None else np.asarray(u)[block_dofs(nodes, dim)]
        sig_el = _cell_stress(m, body.material, part, u_block)       # (nelem, dim, dim)
        t = m.cells if nodes is None else nodes[m.cells]
        per_node = np.repeat(sig_el.reshape(len(t), -1), t.shape[1], axis=0)
        acc += np.column_stack([np.bincount(t.ravel(), per_node[:, c], len(acc))
                                for c in range(dim * dim)]).reshape(acc.shape)
        cnt += np.bincount(t.ravel(), minlength=len(cnt))
    lam, mu = plane_lame(body.material, parts[0])
    s = acc / cnt[:, None, None]
    if dim == 2:
        szz = lam * np.trace(s, axis1=1, axis2=2) / (2 * (lam + mu))  # = nu (sxx + syy)
        if form.kinematics == "plane stress":
            szz = 0.0 * szz
        full = np.zeros((len(s), 3, 3))
        full[:, :2, :2] = s
        full[:, 2, 2] = szz
    else:
        full = s
    dev = full - np.trace(full, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3
    vm = np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))
    return s, vm


def _cell_stress(mesh: Mesh, material, form: Formulation, u: np.ndarray) -> np.ndarray:
    """Mean over the Gauss points of each cell of the stress of displacement ``u``
    (single-type mesh): ``(n_cells, dim, dim)``."""
    lam, mu = plane_lame(material, form)
    quad = batched.cell_quadrature(mesh)
    U = np.asarray(u).reshape(-1, mesh.dim)[quad.nodes]             # (ne, nb, dim)
    gu = np.einsum("eak,eai->eki", U, quad.mean_gradients())         # mean over Gauss points
    eps = 0.5 * (gu + np.swapaxes(gu, 1, 2))
    tr = np.trace(eps, axis1=1, axis2=2)
    return 2 * mu * eps + lam * tr[:, None, None] * np.eye(mesh.dim)
