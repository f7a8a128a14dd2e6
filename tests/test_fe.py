"""Finite element layer: patch test, cantilever convergence to beam theory, loads."""
import numpy as np
import pytest
import scipy.sparse.linalg as spla

from qsma.fe import assemble_body
from qsma.model import Body, Clamp, Mesh, Pressure, read_mesh
from qsma.mesh.generate import structured_mesh
from helpers import STEEL, check_patch, distorted_3d, distorted_patch

@pytest.mark.parametrize("cell_type", ["quad", "triangle"])
def test_patch_uniform_stress_reproduced_on_distorted_mesh(cell_type):
    check_patch(distorted_patch(cell_type), np.array([[1e-3, 2e-4], [-5e-4, 3e-4]]))


def _cantilever(n_thick, L=0.2, h=0.00625):
    m = structured_mesh(np.linspace(0, L, 32 * n_thick + 1), np.linspace(0, h, n_thick + 1))
    m = m.with_sets(node_sets={"clamp": np.flatnonzero(m.points[:, 0] < 1e-12),
                               "tip": np.flatnonzero(m.points[:, 0] > L - 1e-12)})
    return assemble_body(Body("beam", m, STEEL, clamps=(Clamp("clamp"),)))


def _plane_strain_beam(L=0.2, h=0.00625):
    E, nu = STEEL.E / (1 - STEEL.nu ** 2), STEEL.nu / (1 - STEEL.nu)
    I, A = h ** 3 / 12, h
    G = E / (2 * (1 + nu))
    return E, I, A, G


def test_cantilever_tip_deflection_converges_to_timoshenko():
    L, h, P = 0.2, 0.00625, 100.0
    E, I, A, G = _plane_strain_beam(L, h)
    exact = P * L ** 3 / (3 * E * I) + P * L / (5 / 6 * G * A)
    errs = []
    for n in (2, 4, 8):
        a = _cantilever(n, L, h)
        tip = a.body.mesh.nodes("tip")
        f = np.zeros(a.n_dofs)
        f[2 * tip + 1] = P / len(tip)
        K = a.K.tocsr()[a.free][:, a.free]
        u = np.zeros(a.n_dofs)
        u[a.free] = spla.spsolve(K.tocsc(), f[a.free])
        errs.append(abs(u[2 * tip + 1].mean() - exact) / exact)
    rates = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    print("tip deflection rel. errors", errs, "rates", rates)
    assert errs[-1] < 0.01                 # within 1 % of Timoshenko at 8 elements thick
    assert rates[-1] > 1.7                 # bilinear quads converge at O(h^2)


def test_cantilever_bending_frequencies_converge_to_euler_bernoulli():
    L, h = 0.2, 0.00625
    E, I, A, _ = _plane_strain_beam(L, h)
    rho = STEEL.rho
    beta = np.array([1.875104069, 4.694091133])
    exact = beta ** 2 / (2 * np.pi) * np.sqrt(E * I / (rho * A * L ** 4))
    errs = []
    for n in (2, 4, 8):
        a = _cantilever(n, L, h)
        K = a.K.tocsr()[a.free][:, a.free].tocsc()
        M = a.M.tocsr()[a.free][:, a.free].tocsc()
        w2 = np.sort(spla.eigsh(K, k=4, M=M, sigma=0, which="LM")[0])
        f = np.sqrt(w2) / (2 * np.pi)
        # axial mode lies far above the first two bending modes for L/h = 32
        errs.append(np.abs(f[:2] - exact) / exact)
    errs = np.array(errs)
    rates = np.log2(errs[:-1] / errs[1:])
    print("bending frequency rel. errors\n", errs, "\nrates\n", rates)
    assert np.all(errs[-1] < 0.01)
    assert np.all(rates[-1] > 1.7)


def test_pressure_load_resultant_and_direction():
    m = structured_mesh(np.linspace(0, 2, 9), np.linspace(0, 1, 5))
    top = m.boundary_facets_where(lambda p: np.abs(p[:, 1] - 1) < 1e-12)
    m = m.with_sets(facet_sets={"top": top})
    body = Body("b", m, STEEL, pressures=(Pressure("top", 3.0e6),))
    f = assemble_body(body).loads["preload"].reshape(-1, 2)
    assert f.sum(axis=0) == pytest.approx([0.0, -3.0e6 * 2.0], abs=1e-6)


def test_elasticity_form_equals_scikit_fem_model():
    import skfem
    from skfem.models.elasticity import linear_elasticity
    from qsma.fe.assembly import _basis, _elasticity_form
    mesh = distorted_patch("quad")
    _, basis = _basis(mesh)
    lam, mu = STEEL.lame
    K_ref = skfem.asm(linear_elasticity(lam, mu), basis)
    K = skfem.asm(_elasticity_form(lam, mu), basis)
    assert abs(K - K_ref).max() <= 1e-14 * abs(K_ref).max()


# ------------------------------------------------ batched assembly vs scikit-fem forms
from pathlib import Path  # noqa: E402

from qsma.mesh.mesh import mixed_mesh

DATA = Path(__file__).parent / "data"


def _curved(mesh: Mesh) -> Mesh:
    """``mesh`` under the smooth map ``x + 0.03 sin(3 x_rolled)``: every cell distorted,
    quadratic cells with curved edges and faces (the map keeps each cell valid)."""
    p = mesh.points
    return Mesh(p + 0.03 * np.sin(3.0 * np.roll(p, 1, axis=1) + 0.5), mesh.cells,
                mesh.cell_type)


def _quad9_to_triangle6(mesh: Mesh) -> Mesh:
    """Each quad9 cell split along its 0-2 diagonal into two triangle6 cells (the cell
    centre is the diagonal's middle node)."""
    c = mesh.cells
    tri = np.concatenate([c[:, [0, 1, 2, 4, 5, 8]], c[:, [0, 2, 3, 8, 6, 7]]])
    return Mesh(mesh.points, tri, "triangle6")


def batched_case(cell_type) -> Mesh:
    """A small distorted mesh of ``cell_type`` (every type scikit-fem assembles here)."""
    xs = np.linspace(0.0, 1.0, 4)
    if cell_type in ("quad", "triangle"):
        return distorted_patch(cell_type)
    if cell_type in ("hexahedron", "tetra"):
        return distorted_3d(cell_type)
    if cell_type == "triangle6":
        return _curved(_quad9_to_triangle6(structured_mesh(xs, xs, cell_type="quad9")))
    if cell_type == "tetra10":
        return _curved(read_mesh(DATA / "quadratic_box_tet10.msh"))
    axes = [xs, xs] if cell_type.startswith("quad") else [xs, xs[:3], xs]
    return _curved(structured_mesh(*axes, cell_type=cell_type))


def _skfem_reference(mesh, lam, mu, rho):
    """K and M by scikit-fem's form assembly on its own basis, renumbered to qsma DOFs."""
    import skfem
    from qsma.fe.assembly import _elasticity_form, _mass_form
    from qsma.fe.elements import fe_space
    space = fe_space(mesh)
    n = mesh.dim * mesh.n_nodes
    return (space.to_qsma_matrix(skfem.asm(_elasticity_form(lam, mu), space.basis), n),
            space.to_qsma_matrix(skfem.asm(_mass_form(rho), space.basis), n))


def _rel(A, B):
    return abs(A - B).max() / abs(B).max()


ALL_CELL_TYPES = ["triangle", "quad", "tetra", "hexahedron", "triangle6", "quad8", "quad9",
                  "tetra10", "hexahedron20", "hexahedron27"]


@pytest.mark.parametrize("cell_type", ALL_CELL_TYPES)
def test_batched_assembly_equals_scikit_fem_forms(cell_type, monkeypatch):
    """The batched iso-parametric map and element matrices (qsma.fe.batched) give the
    stiffness and the consistent mass of scikit-fem's form assembly to round-off (1e-12
    relative; measured 1e-15), also when the elements are split into batches of 5; the mean stress per cell
    equals the one interpolated on scikit-fem's basis."""
    from qsma.fe import batched
    from qsma.fe.assembly import _cell_stress
    from qsma.fe.elements import fe_space
    from qsma.fe.formulation import resolve_formulation
    mesh = batched_case(cell_type)
    lam, mu = STEEL.lame
    monkeypatch.setattr(batched, "BATCH", 5)
    K_ref, M_ref = _skfem_reference(mesh, lam, mu, STEEL.rho)
    K, M = batched.stiffness(mesh, lam, mu), batched.mass(mesh, STEEL.rho)
    for mine, ref in ((K, K_ref), (M, M_ref)):
        assert mine.has_sorted_indices
        assert _rel(mine, ref) <= 1e-12
    # one pattern, every pair of nodes sharing a cell (scikit-fem drops the zero
    # blocks of the mass; the previous coordinate assembly of qsma kept them)
    assert np.array_equal(K.indptr, M.indptr) and np.array_equal(K.indices, M.indices)
    assert K.nnz >= K_ref.nnz            # (scikit-fem also drops entries that cancel)
    # rigid motions carry no strain energy, the mass sums to rho times the volume
    volume = batched.cell_quadrature(mesh).dx().sum()      # (some rules weigh a point < 0)
    ones = np.tile(np.eye(mesh.dim), mesh.n_nodes)                  # (dim, n_dofs)
    assert np.abs(K @ ones.T).max() <= 1e-12 * abs(K).max()
    assert np.allclose(ones @ M @ ones.T, STEEL.rho * volume * np.eye(mesh.dim), rtol=1e-12)
    u = np.random.default_rng(2).standard_normal(mesh.dim * mesh.n_nodes)
    space = fe_space(mesh)
    gu = space.basis.interpolate(space.from_qsma_vector(u)).grad.mean(axis=-1)
    eps = 0.5 * (gu + np.swapaxes(gu, 0, 1))
    sig_ref = 2 * mu * eps + lam * np.trace(eps)[None, None] * np.eye(mesh.dim)[:, :, None]
    sig = _cell_stress(mesh, STEEL, resolve_formulation(mesh), u)
    assert np.abs(sig - np.moveaxis(sig_ref, -1, 0)).max() <= 1e-12 * np.abs(sig_ref).max()


def test_batched_assembly_of_a_mixed_mesh_sums_its_blocks():
    """A mesh of quads and triangles: K and M are the sums of scikit-fem's matrices of
    each block, scattered to the mesh DOFs (1e-12)."""
    from qsma.fe.elements import block_dofs, scatter_matrix
    from qsma.fe import mass_matrix, stiffness_matrix
    quads = distorted_patch("quad")
    c = quads.cells
    blocks = [("quad", c[::2]), ("triangle", np.concatenate([c[1::2][:, [0, 1, 2]],
                                                              c[1::2][:, [0, 2, 3]]]))]
    mesh = mixed_mesh(quads.points, blocks)
    body = Body("mixed", mesh, STEEL)
    lam, mu = STEEL.lame
    K_ref = M_ref = 0
    n = body.n_dofs
    for m, nodes in mesh.block_meshes():
        K_b, M_b = _skfem_reference(m, lam, mu, STEEL.rho)
        K_ref = K_ref + scatter_matrix(K_b, block_dofs(nodes, 2), n)
        M_ref = M_ref + scatter_matrix(M_b, block_dofs(nodes, 2), n)
    assert _rel(stiffness_matrix(body), K_ref) <= 1e-12
    assert _rel(mass_matrix(body), M_ref) <= 1e-12


def test_block_pattern_sums_duplicates_like_a_coordinate_assembly():
    """Two elements sharing nodes: the summed block matrix equals scipy's COO -> CSR
    conversion of the same element matrices (a small hand case)."""
    import scipy.sparse as sp
    from qsma.fe import batched
    nodes = np.array([[0, 2, 3], [3, 2, 1]])
    dim = 2
    blocks = np.random.default_rng(0).standard_normal((2, 6, 6))
    pattern = batched.block_pattern(nodes, 4)
    B = blocks.reshape(2, 3, dim, 3, dim)
    A = batched.sum_into_csr(lambda i, k: B[:, :, i, :, k], pattern, dim)
    dofs = (dim * nodes[:, :, None] + np.arange(dim)).reshape(2, -1)
    rows = np.repeat(dofs, 6, axis=1).ravel()
    cols = np.tile(dofs, (1, 6)).ravel()
    ref = sp.coo_matrix((blocks.ravel(), (rows, cols)), shape=(8, 8)).toarray()
    assert np.allclose(A.toarray(), ref, rtol=0, atol=1e-14)
    assert A.nnz == 4 * (16 - 2)          # all node pairs but (0, 1) and (1, 0)


@pytest.mark.parametrize("case", [("quad", 2), ("triangle", 2), ("hexahedron", 3),
                                  ("tetra", 3)])
def test_nodal_stress_is_the_average_of_the_element_means_of_the_gauss_stresses(case):
    """``stress_at_nodes`` of a non-uniform field on a distorted mesh equals, to
    round-off, its definition written out: per element the mean over the Gauss points
    of ``C : sym(grad u)`` from the element's own quadrature, then per node the mean
    over the elements that hold it."""
    from qsma.fe import stress_at_nodes
    from qsma.fe.batched import cell_quadrature
    cell_type, dim = case
    mesh = distorted_patch(cell_type) if dim == 2 else distorted_3d(cell_type)
    a = assemble_body(Body("patch", mesh, STEEL))
    x = mesh.points
    u = np.column_stack([x[:, 0] ** 2 * x[:, 1], np.sin(x[:, 0] + 2 * x[:, 1]),
                         x[:, 1] * x[:, -1] ** 2][:dim]).ravel() * 1e-3
    sig, vm = stress_at_nodes(a.body, u)
    quad = cell_quadrature(mesh)
    lam, mu = STEEL.lame
    U = u.reshape(-1, dim)[quad.nodes]
    per_element = []
    for cut, G, _ in quad.batches():
        for e, Ge in zip(U[cut], G):
            s = np.zeros((dim, dim))
            for Gq in Ge:                                   # each Gauss point
                eps = 0.5 * (e.T @ Gq + (e.T @ Gq).T)
                s += 2 * mu * eps + lam * np.trace(eps) * np.eye(dim)
            per_element.append(s / len(Ge))
    expected = np.zeros_like(sig)
    count = np.zeros(len(x))
    for cell, s in zip(mesh.cells, per_element):
        expected[cell] += s
        count[cell] += 1
    expected /= count[:, None, None]
    assert np.abs(sig - expected).max() < 1e-12 * np.abs(expected).max()
    assert np.all(vm >= 0) and np.abs(vm).max() > 0
