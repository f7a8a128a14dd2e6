"""Finite element layer: patch test, cantilever convergence to beam theory, loads."""
import numpy as np
import pytest
import scipy.sparse.linalg as spla

from qsma.fe import assemble_body
from qsma.model import Body, Clamp, Mesh, Pressure
from qsma.model.generate import structured_mesh
from helpers import STEEL, check_patch, distorted_patch

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


@pytest.mark.parametrize("cell_type", ["quad", "triangle", "hexahedron"])
def test_batched_assembly_equals_scikit_fem_forms(cell_type, monkeypatch):
    """The vectorised element matrices (qsma.fe.assembly.elasticity_matrix and
    consistent_mass) equal scikit-fem's form assembly, also when the elements are
    split into several batches."""
    import skfem
    from qsma.fe import assembly
    from qsma.fe.assembly import _basis, _elasticity_form, _mass_form
    if cell_type == "hexahedron":
        xs = np.linspace(0, 1, 4)
        mesh = structured_mesh(xs, xs[:3], xs)
        p = mesh.points + np.random.default_rng(1).uniform(-0.05, 0.05, mesh.points.shape)
        mesh = Mesh(p, mesh.cells, "hexahedron")
    else:
        mesh = distorted_patch(cell_type)
    _, basis = _basis(mesh)
    lam, mu = STEEL.lame
    monkeypatch.setattr(assembly, "ASSEMBLY_BATCH", 5)
    for mine, ref in ((assembly.elasticity_matrix(basis, lam, mu),
                       skfem.asm(_elasticity_form(lam, mu), basis)),
                      (assembly.consistent_mass(basis, STEEL.rho),
                       skfem.asm(_mass_form(STEEL.rho), basis))):
        assert abs(mine - ref).max() <= 1e-14 * abs(ref).max()

