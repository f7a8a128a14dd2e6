"""Element formulations: models anywhere in space, plane stress, quadratic cells,
incompatible modes, refusals of what is not implemented."""
import dataclasses

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from qsma.errors import InputError
from qsma.examples import sandwich_2d, sandwich_3d
from qsma.fe import assemble_body
from qsma.modal import linear_modes
from qsma.model import Model, make_pairing


def translated(model: Model, offset) -> Model:
    """``model`` with every body moved by ``offset`` (m)."""
    bodies = [dataclasses.replace(b, mesh=dataclasses.replace(
        b.mesh, points=b.mesh.points + np.asarray(offset))) for b in model.bodies]
    return dataclasses.replace(model, bodies=tuple(bodies))


def _rel(a, b):
    d = a - b
    d = abs(d).max() if hasattr(d, "tocsr") else np.abs(d).max()
    s = abs(b).max() if hasattr(b, "tocsr") else np.abs(b).max()
    return d / s


@pytest.mark.parametrize("make, offset", [
    (sandwich_2d, (1000.0, -1000.0)),
    (sandwich_3d, (1000.0, 1000.0, -1000.0)),
])
def test_model_translated_by_one_km_gives_same_operators_and_frequency(make, offset):
    """Assembly on coordinates relative to each body's bounding-box corner: K, M, the
    preload and the tied f0 agree to 1e-8 (the translation itself rounds the
    coordinates at 1e3 * 2^-52 = 2e-13 m, 1e-10 of the smallest element)."""
    m0 = make(1)
    m1 = translated(m0, offset)
    A0 = [assemble_body(b) for b in m0.bodies]
    A1 = [assemble_body(b) for b in m1.bodies]
    for a0, a1 in zip(A0, A1):
        assert _rel(a1.K, a0.K) < 1e-8
        assert _rel(a1.M, a0.M) < 1e-8
        assert _rel(a1.loads["preload"], a0.loads["preload"]) < 1e-8
    p0, p1 = make_pairing(m0), make_pairing(m1)
    f0 = linear_modes(m0, A0, p0, n_modes=1).f_hz[0]
    f1 = linear_modes(m1, A1, p1, n_modes=1).f_hz[0]
    assert abs(f1 - f0) < 1e-8 * f0
    # outputs keep the user's coordinates: the pair positions are the moved ones
    assert np.abs(p1.x - (p0.x + np.asarray(offset))).max() < 1e-9
    assert np.abs(p1.area - p0.area).max() < 1e-8 * p0.area.max()


# ---------------------------------------------------------------- quadratic cells
from qsma.model import Body, Clamp, Material, Mesh, Pressure, boundary_facets  # noqa: E402
from qsma.mesh.generate import structured_mesh
from helpers import check_patch, distorted_3d, distorted_patch, needs_ccx  # noqa: E402

STEEL = Material(200e9, 0.285, 7800.0)
A2 = np.array([[1e-3, 2e-4], [-5e-4, 3e-4]])
A3 = np.array([[1e-3, 2e-4, 0.0], [-5e-4, 3e-4, 1e-4], [2e-4, 0.0, -1e-4]])


def quadratic_simplices(mesh: Mesh) -> Mesh:
    """triangle -> triangle6, tetra -> tetra10: a node at the middle of every edge,
    edges in meshio order (triangle6: 01 12 20; tetra10: 01 12 02 03 13 23)."""
    edges = {"triangle": [(0, 1), (1, 2), (2, 0)],
             "tetra": [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]}[mesh.cell_type]
    allf = np.concatenate([np.sort(mesh.cells[:, list(e)], axis=1) for e in edges])
    uniq, inv = np.unique(allf, axis=0, return_inverse=True)
    mid = 0.5 * (mesh.points[uniq[:, 0]] + mesh.points[uniq[:, 1]])
    extra = mesh.n_nodes + inv.ravel().reshape(len(edges), -1).T
    ct = {"triangle": "triangle6", "tetra": "tetra10"}[mesh.cell_type]
    return Mesh(np.vstack([mesh.points, mid]), np.hstack([mesh.cells, extra]), ct)


def _perturb_interior(mesh: Mesh, amp, seed=1) -> Mesh:
    """Move every node off the boundary (corner and midside nodes alike: curved edges)."""
    p = mesh.points.copy()
    inner = np.setdiff1d(np.arange(mesh.n_nodes), np.unique(boundary_facets(mesh)))
    p[inner] += np.random.default_rng(seed).uniform(-amp, amp, size=(len(inner), mesh.dim))
    return Mesh(p, mesh.cells, mesh.cell_type)


def _quadratic_patch(cell_type):
    if cell_type in ("triangle6", "tetra10"):
        lin = distorted_patch("triangle") if cell_type == "triangle6" else distorted_3d("tetra")
        return _perturb_interior(quadratic_simplices(lin), 0.01)
    dim = 2 if cell_type.startswith("quad") else 3
    xs = np.linspace(0, 1, 4)
    m = structured_mesh(*([xs] * dim), cell_type=cell_type)
    return _perturb_interior(m, 0.03)


@pytest.mark.parametrize("cell_type", ["triangle6", "quad8", "quad9", "tetra10",
                                       "hexahedron20", "hexahedron27"])
def test_quadratic_patch_on_curved_distorted_mesh(cell_type):
    """Iso-parametric quadratic cells with curved edges reproduce any linear field
    exactly (x itself is interpolated) and the mass is rho times the volume."""
    mesh = _quadratic_patch(cell_type)
    a = check_patch(mesh, A2 if mesh.dim == 2 else A3)
    assert a.M.sum() / mesh.dim == pytest.approx(STEEL.rho, rel=1e-12)   # unit square/cube
    assert a.formulation.startswith("CPE" if mesh.dim == 2 else "C3D")


@pytest.mark.parametrize("cell_type, corner, mid, centre", [
    # consistent shares of a uniform pressure on one facet (integrals of the facet's
    # shape functions over its reference domain / area): line3 1/6 2/3; quad8 -1/12
    # (corners) 1/3 (midsides); quad9 1/36 1/9 4/9; triangle6 0 1/3
    ("quad8", 1 / 6, 2 / 3, None),
    ("hexahedron20", -1 / 12, 1 / 3, None),
    ("hexahedron27", 1 / 36, 1 / 9, 4 / 9),
])
def test_pressure_on_one_quadratic_facet_gives_consistent_nodal_shares(cell_type, corner,
                                                                      mid, centre):
    dim = 2 if cell_type.startswith("quad") else 3
    m = structured_mesh(*([np.array([0.0, 2.0])] * dim), cell_type=cell_type)
    top = m.boundary_facets_where(lambda p: np.abs(p[:, 1] - 2.0) < 1e-12)
    m = m.with_sets(facet_sets={"top": top})
    p = 3.0e6
    f = assemble_body(Body("b", m, STEEL, pressures=(Pressure("top", p),))).loads["preload"]
    fy = f.reshape(-1, dim)[:, 1]
    area = 2.0 ** (dim - 1)
    row = top[0]
    nc = 2 if dim == 2 else 4
    assert fy[row[:nc]] == pytest.approx(-p * area * corner * np.ones(nc), rel=1e-12)
    nm = 1 if dim == 2 else 4
    assert fy[row[nc:nc + nm]] == pytest.approx(-p * area * mid * np.ones(nm), rel=1e-12)
    if centre is not None:
        assert fy[row[-1]] == pytest.approx(-p * area * centre, rel=1e-12)
    assert fy.sum() == pytest.approx(-p * area, rel=1e-12)
    assert np.abs(f.reshape(-1, dim)[:, [0] + list(range(2, dim))]).max() < 1e-6 * p


L_BEAM, H_BEAM = 0.2, 0.00625
BETA = np.array([1.875104069, 4.694091133])   # clamped-free roots of cos b cosh b = -1


def cantilever_frequencies(cell_type, n, element=None, dim=2, nx=32, k=2):
    """First ``k`` frequencies (Hz) of a steel cantilever L = 0.2 m, h = 6.25 mm (square
    section in 3D), ``n`` cells through the thickness and ``nx * n`` along."""
    axes = [np.linspace(0, L_BEAM, nx * n + 1)] + [np.linspace(0, H_BEAM, n + 1)] * (dim - 1)
    m = structured_mesh(*axes, cell_type=cell_type)
    m = m.with_sets(node_sets={"clamp": np.flatnonzero(m.points[:, 0] < 1e-12)})
    if element is not None:
        m = dataclasses.replace(m, element=element)
    a = assemble_body(Body("beam", m, STEEL, clamps=(Clamp("clamp"),)))
    K = a.K[a.free][:, a.free].tocsc()
    M = a.M[a.free][:, a.free].tocsc()
    w2 = np.sort(spla.eigsh(K, k=2 * k, M=M, sigma=0, which="LM")[0])
    return np.sqrt(w2) / (2 * np.pi), a


def euler_bernoulli(dim, E=None):
    """Clamped-free bending frequencies; plane strain uses E / (1 - nu^2)."""
    if E is None:
        E = STEEL.E / (1 - STEEL.nu ** 2) if dim == 2 else STEEL.E
    I, A = (H_BEAM ** 3 / 12, H_BEAM) if dim == 2 else (H_BEAM ** 4 / 12, H_BEAM ** 2)
    return BETA ** 2 / (2 * np.pi) * np.sqrt(E * I / (STEEL.rho * A * L_BEAM ** 4))


@pytest.mark.parametrize("cell_type, tol1", [
    # measured relative errors of f1 at one cell through the thickness (printed by
    # cantilever_frequencies above; table in docs/validation.md): quad 0.24, quad8
    # 2.3e-3, quad9 7.4e-4
    ("quad8", 3e-3), ("quad9", 1e-3)])
def test_quadratic_cantilever_bending_one_cell_thick(cell_type, tol1):
    ex = euler_bernoulli(2)
    errs = [(cantilever_frequencies(cell_type, n)[0][0] - ex[0]) / ex[0] for n in (1, 2)]
    assert abs(errs[0]) < tol1
    assert abs(errs[1]) < 0.5 * abs(errs[0])          # converging
    assert abs(errs[1]) < 5e-4                       # shear + rotary inertia ~1e-4 (L/h = 32)


@pytest.mark.parametrize("cell_type", ["hexahedron20", "hexahedron27"])
def test_quadratic_hexahedra_cantilever_one_cell_thick(cell_type):
    """Q1 hexahedra are 24 % too stiff with one cell through the thickness; serendipity
    and Lagrange quadratic bricks are within 0.3 % of Euler-Bernoulli (measured 2.9e-3
    and 1.7e-3)."""
    f, _ = cantilever_frequencies(cell_type, 1, dim=3, k=1)
    ex = euler_bernoulli(3)[0]
    assert abs(f[0] - ex) / ex < 3e-3


# ---------------------------------------------------------------- incompatible modes
import scipy.sparse as sp  # noqa: E402
from qsma.fe.incompatible import element_stiffness  # noqa: E402


def _global(mesh, Ke):
    dim = mesh.dim
    nd = Ke.shape[1]
    d = (dim * mesh.cells[:, :, None] + np.arange(dim)).reshape(len(mesh.cells), nd)
    n = dim * mesh.n_nodes
    return sp.csr_matrix((Ke.ravel(), (np.repeat(d, nd, 1).ravel(), np.tile(d, (1, nd)).ravel())),
                         shape=(n, n))


@pytest.mark.parametrize("mesh", [distorted_patch("quad"), distorted_3d("hexahedron")],
                         ids=["quad", "hexahedron"])
def test_hand_assembly_without_modes_equals_scikit_fem(mesh):
    """The hand-written element loop with the modes switched off is scikit-fem's Q1."""
    lam, mu = STEEL.lame
    K = _global(mesh, element_stiffness(mesh.points[mesh.cells], lam, mu, modes=False))
    K_ref = assemble_body(Body("p", mesh, STEEL)).K
    assert abs(K - K_ref).max() <= 1e-13 * abs(K_ref).max()


def _interior_error(K, mesh, A):
    """Relative error of the interior displacement when ``u = A x`` is imposed on the
    boundary nodes (zero for an element that passes the patch test)."""
    dim = mesh.dim
    u = (mesh.points @ A.T).ravel()
    bnd = np.unique(boundary_facets(mesh))
    B = (dim * bnd[:, None] + np.arange(dim)).ravel()
    I = np.setdiff1d(np.arange(K.shape[0]), B)
    uI = spla.spsolve(K[I][:, I].tocsc(), -K[I][:, B] @ u[B])
    return np.abs(uI - u[I]).max() / np.abs(u).max()


@pytest.mark.parametrize("element, mesh, A", [
    ("CPE4I", distorted_patch("quad"), A2), ("C3D8I", distorted_3d("hexahedron"), A3)])
def test_incompatible_patch_on_distorted_mesh(element, mesh, A):
    a = check_patch(dataclasses.replace(mesh, element=element), A)
    assert "incompatible modes" in a.formulation


def test_plane_stress_incompatible_patch_on_distorted_mesh():
    mesh = dataclasses.replace(distorted_patch("quad"), element="CPS4I")
    a = assemble_body(Body("p", mesh, STEEL))
    assert _interior_error(a.K, mesh, A2) < 1e-12
    assert a.formulation.startswith("CPS4I: plane stress")


@pytest.mark.parametrize("mesh", [distorted_patch("quad"), distorted_3d("hexahedron")],
                         ids=["quad", "hexahedron"])
def test_wilson_element_without_taylor_correction_fails_the_patch_test(mesh):
    """The reason for Taylor's correction: with the local Jacobian in the mode gradients,
    a linear boundary displacement on a distorted mesh is not reproduced inside."""
    lam, mu = STEEL.lame
    K = _global(mesh, element_stiffness(mesh.points[mesh.cells], lam, mu, taylor=False))
    assert _interior_error(K, mesh, A2 if mesh.dim == 2 else A3) > 1e-4


def test_incompatible_cantilever_one_element_thick():
    """One incompatible-mode element through the thickness: f1 within 0.1 % (2D) and
    0.2 % (3D) of Euler-Bernoulli where full-integration Q1 is 24 % too stiff (measured
    -6.0e-4 for CPE4I, 1.5e-3 for C3D8I; the 3D limit itself lies ~1e-3 above
    Euler-Bernoulli, see the hexahedron27 cantilever)."""
    f2 = cantilever_frequencies("quad", 1, element="CPE4I")[0][0]
    f3 = cantilever_frequencies("hexahedron", 1, element="C3D8I", dim=3, k=1)[0][0]
    q1 = cantilever_frequencies("quad", 1, element="CPE4")[0][0]
    ex2, ex3 = euler_bernoulli(2)[0], euler_bernoulli(3)[0]
    assert abs(f2 - ex2) / ex2 < 1e-3 and abs(f3 - ex3) / ex3 < 2e-3
    assert (q1 - ex2) / ex2 > 0.2


def test_plane_stress_cantilever_uses_young_modulus():
    """CPS: the beam modulus is E (plane strain: E / (1 - nu^2)); frequencies ratio
    sqrt(1 - nu^2) at the same mesh up to the (small) Poisson coupling of the solid."""
    fe = cantilever_frequencies("quad8", 2, element="CPS8")
    fs = fe[0][0]
    assert "plane stress" in fe[1].formulation
    ex = euler_bernoulli(2, E=STEEL.E)[0]
    assert abs(fs - ex) / ex < 5e-4
    fp = cantilever_frequencies("quad8", 2)[0][0]
    assert fp / fs == pytest.approx(1 / np.sqrt(1 - STEEL.nu ** 2), rel=2e-3)


# ---------------------------------------------------------------- formulation names
from qsma.fe import resolve_formulation  # noqa: E402


@pytest.mark.parametrize("cell_type, element, label", [
    ("quad", None, "CPE4: plane strain"), ("quad", "CPE4", "CPE4: plane strain"),
    ("quad", "cps4", "CPS4: plane stress"), ("quad", "CPE4I", "CPE4I: plane strain"),
    ("quad8", "CPS8", "CPS8: plane stress"), ("triangle6", "CPE6", "CPE6: plane strain"),
    ("hexahedron", "C3D8I", "C3D8I: 8-node hexahedron"),
    ("tetra10", "C3D10", "C3D10: 10-node tetrahedron"),
    ("hexahedron20", None, "C3D20: 20-node hexahedron (serendipity)")])
def test_formulation_resolved_from_mesh_element(cell_type, element, label):
    dim = 3 if cell_type in ("hexahedron", "tetra10", "hexahedron20") else 2
    m = _quadratic_patch(cell_type) if cell_type in ("quad8", "triangle6", "tetra10",
                                                     "hexahedron20") else \
        (distorted_patch("quad") if dim == 2 else distorted_3d("hexahedron"))
    form = resolve_formulation(dataclasses.replace(m, element=element))
    assert form.label.startswith(label)


@pytest.mark.parametrize("cell_type, element, words", [
    ("quad", "CAX4", "axisymmetric"), ("quad", "CPE4R", "reduced integration"),
    ("hexahedron", "C3D8R", "C3D8I"), ("hexahedron", "C3D8H", "hybrid"),
    ("quad", "CPE8", "disagree"), ("quad", "C3D8", "does not fit"),
    ("quad", "S4R", "not an element"), ("quad8", "CPE8I", "CPE4I/CPS4I/C3D8I only")])
def test_unimplemented_formulations_are_refused_not_replaced(cell_type, element, words):
    m = _quadratic_patch(cell_type) if cell_type == "quad8" else distorted_patch("quad") \
        if cell_type == "quad" else distorted_3d("hexahedron")
    with pytest.raises(InputError, match=words):
        assemble_body(Body("b", dataclasses.replace(m, element=element), STEEL))


# ---------------------------------------------------------------- CalculiX comparison
import os  # noqa: E402
import re  # noqa: E402
import subprocess  # noqa: E402

from helpers import HEX_TO_TETS  # noqa: E402



def ccx_deck(mesh, etype, k):
    """A CalculiX frequency deck of a steel cantilever clamped at x = 0 (meshio node
    orders are those of C3D4/C3D8/C3D10/C3D20)."""
    lines = ["*NODE"] + [f"{i + 1}, {x:.17g}, {y:.17g}, {z:.17g}"
                         for i, (x, y, z) in enumerate(mesh.points)]
    lines.append(f"*ELEMENT, TYPE={etype}, ELSET=EALL")
    for e, c in enumerate(mesh.cells):
        row = [str(e + 1)] + [str(v + 1) for v in c]
        lines += [", ".join(row[:16]) + ("," if len(row) > 16 else "")] + \
            ([", ".join(row[16:])] if len(row) > 16 else [])
    clamp = np.flatnonzero(mesh.points[:, 0] < 1e-12) + 1
    lines.append("*NSET, NSET=CLAMP")
    lines += [", ".join(map(str, clamp[i:i + 8])) for i in range(0, len(clamp), 8)]
    lines += ["*MATERIAL, NAME=STEEL", "*ELASTIC", f"{STEEL.E:.17g}, {STEEL.nu:.17g}",
              "*DENSITY", f"{STEEL.rho:.17g}", "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL",
              "*BOUNDARY", "CLAMP, 1, 3", "*STEP", "*FREQUENCY", f"{k}", "*END STEP"]
    return "\n".join(lines) + "\n"


def ccx_frequencies(mesh, etype, tmp_path, k=4):
    """First ``k`` frequencies (Hz) CalculiX computes for the deck (printed with 7
    significant digits in the .dat file: resolution ~4e-7 relative)."""
    (tmp_path / "job.inp").write_text(ccx_deck(mesh, etype, k))
    subprocess.run(["ccx", "-i", "job"], cwd=tmp_path, capture_output=True, check=True,
                   env={**os.environ, "OMP_NUM_THREADS": "1"})
    blk = (tmp_path / "job.dat").read_text().split("E I G E N V A L U E   O U T P U T")[1]
    rows = re.findall(r"^\s*(\d+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s*$", blk, re.M)
    return np.array([float(r[3]) for r in rows[:k]])          # cycles / time


def _qsma_frequencies(mesh, k=4):
    m = mesh.with_sets(node_sets={"clamp": np.flatnonzero(mesh.points[:, 0] < 1e-12)})
    a = assemble_body(Body("b", m, STEEL, clamps=(Clamp("clamp"),)))
    w2 = np.sort(spla.eigsh(a.K[a.free][:, a.free].tocsc(), k=k,
                            M=a.M[a.free][:, a.free].tocsc(), sigma=0, which="LM")[0])
    return np.sqrt(w2) / (2 * np.pi)


def _cantilever_mesh(cell_type):
    axes = [np.linspace(0, L_BEAM, 33)] + [np.linspace(0, H_BEAM, 2)] * 2
    if cell_type != "tetra10":
        return structured_mesh(*axes, cell_type=cell_type)
    m = structured_mesh(*axes)
    tets = np.concatenate([m.cells[:, list(t)] for t in HEX_TO_TETS])
    return quadratic_simplices(Mesh(m.points, tets, "tetra"))


@needs_ccx
@pytest.mark.parametrize("cell_type, etype", [("hexahedron", "C3D8"),
                                              ("hexahedron20", "C3D20"),
                                              ("tetra10", "C3D10")])
def test_same_formulation_as_calculix_gives_same_frequencies(cell_type, etype, tmp_path):
    """Same deck, same element: the first four frequencies agree to CalculiX's printed
    precision (measured: 1.4e-7 C3D8, 8e-8 C3D20, 7e-7 C3D10)."""
    mesh = _cantilever_mesh(cell_type)
    fc = ccx_frequencies(mesh, etype, tmp_path)
    fq = _qsma_frequencies(mesh)
    assert np.all(np.abs(fq - fc) / fc < 1.5e-6)


@needs_ccx
def test_c3d8i_differs_from_calculix_only_by_the_mass_of_the_modes(tmp_path):
    """CalculiX's C3D8I keeps the 9 incompatible-mode parameters of every element as
    global unknowns and gives them mass (consistent mass with the functions 1 - xi_i^2,
    its shape8humass.f); qsma condenses them statically (massless modes). With the modes
    given mass here, the frequencies agree with CalculiX to its printed precision
    (measured 3e-7); qsma's own C3D8I differs by 7e-5 (first bending pair) and 1.1e-3
    (second pair) on this one-element-thick beam, both converging to the same limit."""
    mesh = _cantilever_mesh("hexahedron")
    fc = ccx_frequencies(mesh, "C3D8I", tmp_path)
    fq = _qsma_frequencies(dataclasses.replace(mesh, element="C3D8I"))
    assert np.all(np.abs(fq - fc) / fc < 2e-3)
    # the same element with massive modes, every mode parameter a global unknown
    from qsma.fe.incompatible import corner_shape_gradients, gauss_points, mode_shape_values
    lam, mu = STEEL.lame
    X = mesh.points[mesh.cells]
    ne = len(X)
    Kf = element_stiffness(X, lam, mu, condensed=False)                 # (ne, 33, 33)
    xi = gauss_points(3)
    signs = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                      [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)
    F = np.concatenate([np.prod(1 + signs[None] * xi[:, None, :], axis=2) / 8,
                        mode_shape_values(xi)], axis=1)                   # (nq, 11)
    detJ = np.linalg.det(np.einsum("eai,qaj->eqij", X, corner_shape_gradients(xi)))
    Ms = STEEL.rho * np.einsum("eq,qa,qb->eab", detJ, F, F)
    Mf = np.einsum("eab,ij->eaibj", Ms, np.eye(3)).reshape(ne, 33, 33)
    dofs = np.concatenate([3 * mesh.cells[:, :, None] + np.arange(3),
                           (3 * mesh.n_nodes + 9 * np.arange(ne))[:, None, None]
                           + np.arange(9).reshape(1, 3, 3)], axis=1).reshape(ne, 33)
    n = 3 * mesh.n_nodes + 9 * ne
    rc = (np.repeat(dofs, 33, 1).ravel(), np.tile(dofs, (1, 33)).ravel())
    K = sp.csr_matrix((Kf.ravel(), rc), shape=(n, n))
    M = sp.csr_matrix((Mf.ravel(), rc), shape=(n, n))
    clamp = np.flatnonzero(mesh.points[:, 0] < 1e-12)
    free = np.setdiff1d(np.arange(n), (3 * clamp[:, None] + np.arange(3)).ravel())
    w2 = np.sort(spla.eigsh(K[free][:, free].tocsc(), k=4, M=M[free][:, free].tocsc(),
                            sigma=0, which="LM")[0])
    f_massive = np.sqrt(w2) / (2 * np.pi)
    assert np.all(np.abs(f_massive - fc) / fc < 1.5e-6)


@pytest.mark.parametrize("cell_type", ["triangle6", "quad8", "quad9", "tetra10",
                                       "hexahedron20", "hexahedron27"])
def test_boundary_facets_and_normals_of_quadratic_cells(cell_type):
    """Boundary of the unit square / cube: facets of the right type (corner nodes first,
    midside nodes at the middle of the corner edges), outward normals summing to zero,
    areas to the perimeter (4) / surface (6), each normal along an axis."""
    from qsma.mesh.facets import facet_normals
    from qsma.mesh.celltypes import TYPES
    mesh = _quadratic_patch(cell_type)
    bf = boundary_facets(mesh)
    assert bf.shape[1] == TYPES[mesh.facet_type].n_nodes
    nc = TYPES[mesh.facet_type].corners
    p = mesh.points[bf]
    if mesh.facet_type in ("line3", "triangle6", "quad8", "quad9"):   # first midside node
        assert np.allclose(p[:, nc], 0.5 * (p[:, 0] + p[:, 1]), atol=1e-12)
    n = facet_normals(mesh, bf)
    area = np.linalg.norm(n, axis=1)
    assert np.abs(n.sum(axis=0)).max() < 1e-12
    assert area.sum() == pytest.approx(2 * mesh.dim, rel=1e-12)
    assert np.allclose(np.abs(n / area[:, None]).max(axis=1), 1.0)
    centre = np.full(mesh.dim, 0.5)
    assert np.all(np.einsum("ij,ij->i", n, p.mean(axis=1) - centre) > 0)     # outward


def test_with_sets_keeps_the_element_name():
    """Adding sets must not silently drop the formulation the source file named."""
    m = dataclasses.replace(distorted_patch("quad"), element="CPS4I")
    assert m.with_sets(node_sets={"a": [0]}).element == "CPS4I"
    assert "plane stress" in assemble_body(Body("b", m.with_sets(), STEEL)).formulation


# ---------------------------------------------------------------- contact on quadratic faces
def _pressed_blocks(cell_type, n=4, h=0.05, w=0.1):
    """Two blocks (w x h x w, one on the other), each clamped on its face x = 0 and
    pressed together by 1 MPa on its outer face; interface: the faces y = h with
    x >= w / n (clear of the clamp)."""
    from qsma.model import Interface, Model, Probe
    eps = 1e-9

    def block(y0, top):
        xs = np.linspace(0, w, n + 1)
        m = structured_mesh(xs, np.linspace(y0, y0 + h, 3), xs, cell_type=cell_type)
        y_if, y_out = (y0, y0 + h) if top else (y0 + h, y0)
        fs = {"interface": m.boundary_facets_where(
                  lambda p: (np.abs(p[:, 1] - y_if) < eps) & (p[:, 0] > w / n - eps)),
              "outer": m.boundary_facets_where(lambda p: np.abs(p[:, 1] - y_out) < eps)}
        ns = {"left": np.flatnonzero(m.points[:, 0] < eps),
              "tip": np.flatnonzero(np.abs(m.points[:, 1] - y_out) < eps)}
        return Body("top" if top else "bottom", m.with_sets(node_sets=ns, facet_sets=fs),
                    STEEL, clamps=(Clamp("left"),), pressures=(Pressure("outer", 1e6),))
    return Model((block(0.0, False), block(h, True)),
                 Interface("bottom", "interface", "top", "interface"),
                 tip=Probe((("top", "tip"),), (0.0, 1.0, 0.0)))


@pytest.mark.parametrize("cell_type, corners_open", [("hexahedron27", False),
                                                      ("hexahedron20", True)])
def test_serendipity_faces_open_their_corner_pairs_under_a_preload(cell_type,
                                                                   corners_open):
    """Node-to-node contact on 8-node faces: the consistent share of a uniform pressure
    at a face corner is -1/12 of the face's force (test above), which a unilateral
    contact cannot carry, so every corner pair opens and the midside pairs carry the
    whole preload (measured: 20 of 20 corner pairs open, tied f1 0.2 % below tying
    them too). 9-node faces (shares 1/36, 1/9, 4/9) keep every pair closed."""
    from qsma.analysis import preload
    import warnings
    from qsma.errors import QuadraticFacetWarning
    model = _pressed_blocks(cell_type)
    A = [assemble_body(b) for b in model.bodies]
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        pairing = make_pairing(model)
    said = [w for w in seen if issubclass(w.category, QuadraticFacetWarning)]
    assert len(said) == (1 if corners_open else 0)       # the user is told, once
    if said:
        assert "corner pairs" in str(said[0].message) and "hexahedron27" in \
            str(said[0].message)
    _, _, pre = preload(model, A, pairing)
    step = 0.1 / 4
    on_grid = lambda v: np.abs(v / step - np.round(v / step)) < 1e-6
    corner = on_grid(pairing.x[:, 0]) & on_grid(pairing.x[:, 2])
    opened = pre.status == 2
    normal = pre.lam[:, -1]
    if corners_open:
        assert np.all(opened[corner]) and not np.any(opened[~corner])
        assert np.abs(normal[corner]).max() < 1e-9 * normal.max()
    else:
        assert not np.any(opened)
        assert normal[corner].min() > 0


def _stacked_blocks_tied(cell_type, p=1e6, n=3):
    """Two unit blocks stacked along y (nu = 0), on rollers (u_x = 0 on x = 0, u_z = 0
    on z = 0, u_y = 0 under the bottom block), pressure ``p`` on the top face, every
    interface pair tied. The exact solution is the uniform stress sigma_yy = -p, which
    every element reproduces (patch test). Returns the pairing and the force each pair
    transmits (on body 1, y component)."""
    from qsma.model import Interface, Model
    dim = 3 if cell_type.startswith("hex") else 2
    mat = Material(200e9, 0.0, 7800.0)
    xs = np.linspace(0, 1, n + 1)

    def block(y0, top):
        axes = [xs, np.linspace(y0, y0 + 1, n + 1)] + [xs] * (dim - 2)
        m = structured_mesh(*axes, cell_type=cell_type)
        y = m.points[:, 1]
        fs = {"interface": m.boundary_facets_where(
                  lambda q: np.abs(q[:, 1] - (y0 if top else y0 + 1)) < 1e-9),
              "top": m.boundary_facets_where(lambda q: np.abs(q[:, 1] - 2) < 1e-9)}
        ns = {"x0": np.flatnonzero(m.points[:, 0] < 1e-9),
              "y0": np.flatnonzero(np.abs(y) < 1e-9)}
        if dim == 3:
            ns["z0"] = np.flatnonzero(m.points[:, 2] < 1e-9)
        return Body("top" if top else "bottom", m.with_sets(node_sets=ns, facet_sets=fs),
                    mat, pressures=(Pressure("top", p),) if top else ())
    model = Model((block(0.0, False), block(1.0, True)),
                  Interface("bottom", "interface", "top", "interface"))
    pairing = make_pairing(model)
    A = [assemble_body(b) for b in model.bodies]
    n1 = A[0].n_dofs
    # unknowns: all DOFs of both bodies; tie u_top[pair] = u_bottom[pair] by elimination
    keep = np.ones(n1 + A[1].n_dofs, dtype=bool)
    T = np.arange(n1 + A[1].n_dofs)
    for c in range(dim):
        T[n1 + dim * pairing.nodes2 + c] = dim * pairing.nodes1 + c
        keep[n1 + dim * pairing.nodes2 + c] = False
    import scipy.sparse as sp
    K = sp.block_diag([A[0].K, A[1].K]).tocsr()
    f = np.concatenate([np.zeros(n1), A[1].loads["preload"]])
    P = sp.csr_matrix((np.ones(len(T)), (np.arange(len(T)), T)), shape=(len(T), len(T)))
    fixed = [dim * model.bodies[0].mesh.nodes("y0") + 1]
    for k, b in enumerate(model.bodies):
        fixed.append(k * n1 + dim * b.mesh.nodes("x0"))
        if dim == 3:
            fixed.append(k * n1 + dim * b.mesh.nodes("z0") + 2)
    free = np.setdiff1d(np.flatnonzero(keep), np.concatenate(fixed))
    Kr = (P.T @ K @ P).tocsr()
    u_r = np.zeros(len(T))
    u_r[free] = spla.spsolve(Kr[free][:, free].tocsc(), (P.T @ f)[free])
    u = P @ u_r
    strain = u[1:n1:dim].reshape(-1)                   # u_y of the bottom block = -p/E y
    y = model.bodies[0].mesh.points[:, 1]
    assert np.abs(strain + p / mat.E * y).max() < 1e-12 * p / mat.E
    force = (A[0].K @ u[:n1])[dim * pairing.nodes1 + 1]      # on body 1, from body 2
    return pairing, force


@pytest.mark.parametrize("cell_type", ["quad8", "quad9", "hexahedron27", "hexahedron20",
                                       "hexahedron"])
def test_uniform_pressure_through_quadratic_interface(cell_type):
    """A uniform pressure crosses a tied quadratic interface exactly (sigma_yy = -p in
    both blocks), each pair carrying the consistent share of its facets. The pressure
    reported per pair, force / tributary area (``Pairing.area``: positive HRZ weights
    on quadratic facets), is then p exactly on line3 and quad9 facets, where the
    weights equal the consistent shares. On serendipity quad8 facets (hexahedron20) the
    corner pairs must pull (-1/12 of each facet's force per corner), which unilateral
    contact cannot do (the preload opens them:
    test_serendipity_faces_open_their_corner_pairs_under_a_preload); the reported
    corner pressures are negative, the midside ones above p."""
    p = 1e6
    pairing, force = _stacked_blocks_tied(cell_type, p)
    assert np.all(pairing.area > 0)
    assert pairing.area.sum() == pytest.approx(1.0, rel=1e-13)          # unit face
    assert -force.sum() == pytest.approx(p, rel=1e-10)
    pressure = -force / pairing.area
    if cell_type != "hexahedron20":
        assert np.abs(pressure / p - 1).max() < 1e-9
    else:
        corner = np.all(np.abs(pairing.x[:, [0, 2]] * 3 - np.round(pairing.x[:, [0, 2]] * 3))
                        < 1e-9, axis=1)
        assert np.all(pressure[corner] < 0) and np.all(pressure[~corner] > p)


@pytest.mark.parametrize("facet_type, shares", [
    ("line", [1 / 2] * 2), ("line3", [1 / 6, 1 / 6, 2 / 3]),
    ("triangle", [1 / 3] * 3), ("triangle6", [1 / 19] * 3 + [16 / 57] * 3),
    ("quad", [1 / 4] * 4), ("quad8", [3 / 76] * 4 + [4 / 19] * 4),
    ("quad9", [1 / 36] * 4 + [1 / 9] * 4 + [4 / 9]),
])
def test_tributary_weights_of_facets_are_positive_hrz_shares(facet_type, shares):
    """HRZ lumping of the facet mass: positive, summing to the area; the consistent
    shares where those are positive (line3, quad9), 3/76 : 4/19 on quad8 (consistent:
    -1/12 : 1/3) and 1/19 : 16/57 on triangle6 (consistent: 0 : 1/3). Checked on a
    stretched, translated facet (shares are relative to its area)."""
    from qsma.mesh.celltypes import TYPES, reference_nodes
    from qsma.mesh.facets import facet_node_weights
    ref = reference_nodes(facet_type)
    scale = {"line": 2.0, "triangle": 0.5, "quad": 4.0}[TYPES[facet_type].linear]
    pts = np.column_stack([ref, np.zeros((len(ref), 2 - ref.shape[1] + 1))])
    pts = pts[:, :3] * [3.0, 0.5, 1.0] + [10.0, -4.0, 2.0]
    if ref.shape[1] == 1:
        pts = pts[:, :2]
    area = scale * 3.0 * (0.5 if ref.shape[1] == 2 else 1.0)
    w = facet_node_weights(pts, [list(range(len(ref)))], facet_type)[0]
    assert np.allclose(w / area, shares, rtol=1e-12, atol=0)


def test_quadratic_sandwich_damping_curve_converges_to_the_fine_linear_one():
    """sandwich-2d with quad8 cells (line3 interface facets, twice the pairs) at the
    spec's grid against the linear Q1 meshes: the quad8 zeta curve lies within 1.5 % of
    Q1 refine 2 at every level (Q1 refine 1: 4.7 % off), and its last-level zeta within
    0.3 % of Q1 refine 4, 0.11159 (``python benchmarks/bench_elements.py --refine 1 2 4
    --zeta``, docs/validation.md), where Q1 refine 1 is 1.8 % low (measured: quad8
    0.11170, Q1 refine 1 0.10956, refine 2 0.11116)."""
    import qsma
    runs = {key: qsma.run(sandwich_2d(r, element=e))
            for key, (r, e) in {"q8": (1, "quad8"), "q1": (1, "quad"),
                                "q2": (2, "quad")}.items()}
    assert all(res.success for res in runs.values())
    ref = runs["q2"].zeta
    dev = {k: np.abs(res.zeta - ref).max() / ref.max() for k, res in runs.items()}
    assert dev["q8"] < 0.015 < dev["q1"]
    fine_linear = 0.11159
    assert abs(runs["q8"].zeta[-1] / fine_linear - 1) < 3e-3
    assert abs(runs["q1"].zeta[-1] / fine_linear - 1) > 1e-2
