"""3D finite elements: patch test on distorted hexahedra and tetrahedra, cantilever."""
import numpy as np
import pytest
import scipy.sparse.linalg as spla

from qsma.fe import assemble_body
from qsma.model import Body, Clamp
from qsma.mesh.generate import structured_mesh
from helpers import STEEL, check_patch, distorted_3d

@pytest.mark.parametrize("cell_type", ["hexahedron", "tetra"])
def test_patch_3d(cell_type):
    A = np.array([[1e-3, 2e-4, 0.0], [-5e-4, 3e-4, 1e-4], [2e-4, 0.0, -1e-4]])
    a = check_patch(distorted_3d(cell_type), A)
    assert a.M.sum() / 3 == pytest.approx(STEEL.rho, rel=1e-12)     # unit cube mass


def test_cantilever_3d_converges_to_beam_theory():
    L, h = 0.2, 0.00625
    I, A = h ** 4 / 12, h * h
    E, G = STEEL.E, STEEL.E / (2 * (1 + STEEL.nu))
    P = 100.0
    exact = P * L ** 3 / (3 * E * I) + P * L / (5 / 6 * G * A)
    beta = 1.875104069
    f_exact = beta ** 2 / (2 * np.pi) * np.sqrt(E * I / (STEEL.rho * A * L ** 4))
    errs, ferrs = [], []
    for n in (1, 2, 4):
        m = structured_mesh(np.linspace(0, L, 32 * n + 1), np.linspace(0, h, n + 1),
                            np.linspace(0, h, n + 1))
        m = m.with_sets(node_sets={"clamp": np.flatnonzero(m.points[:, 0] < 1e-12),
                                   "tip": np.flatnonzero(m.points[:, 0] > L - 1e-12)})
        a = assemble_body(Body("beam", m, STEEL, clamps=(Clamp("clamp"),)))
        tip = m.nodes("tip")
        f = np.zeros(a.n_dofs)
        f[3 * tip + 1] = P / len(tip)
        K = a.K.tocsr()[a.free][:, a.free].tocsc()
        u = np.zeros(a.n_dofs)
        u[a.free] = spla.spsolve(K, f[a.free])
        errs.append(abs(u[3 * tip + 1].mean() - exact) / exact)
        Mff = a.M.tocsr()[a.free][:, a.free].tocsc()
        w2 = np.sort(spla.eigsh(K, k=2, M=Mff, sigma=0, which="LM")[0])
        ferrs.append(abs(np.sqrt(w2[0]) / (2 * np.pi) - f_exact) / f_exact)
    rate = np.log2(errs[-2] / errs[-1])
    frate = np.log2(ferrs[-2] / ferrs[-1])
    print("3D cantilever tip errors", errs, "rate", rate, "f1 errors", ferrs, "rate", frate)
    assert errs[-1] < 0.04 and rate > 1.7
    assert ferrs[-1] < 0.02 and frate > 1.7
