"""Static condensation: exactness against the full sparse model."""
import numpy as np
import pytest
import scipy.sparse.linalg as spla

from qsma.reduction.two_bodies import reduce_two_bodies
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.modal import linear_modes, stacked, tie_transform
from qsma.model import make_pairing


@pytest.fixture(scope="module")
def setup():
    m = sandwich_2d(1)
    A = [assemble_body(b) for b in m.bodies]
    p = make_pairing(m)
    return m, A, p, reduce_two_bodies(A[0], A[1], p)


def test_condensed_relation_and_recovery_match_full_solve(setup):
    m, A, p, rm = setup
    rng = np.random.default_rng(1)
    for a, body in zip(A, rm.bodies):
        uC_local = rng.normal(size=len(body.C)) * 1e-6
        F = a.loads["preload"] * rng.uniform(0.5, 2.0)
        # full solve with the interface DOFs prescribed
        K = a.K.tocsr()
        uC = body.R @ uC_local
        uE = spla.spsolve(K[body.E][:, body.E].tocsc(), F[body.E] - K[body.E][:, body.C] @ uC)
        u_full = np.zeros(a.n_dofs)
        u_full[body.C], u_full[body.E] = uC, uE
        reaction = K[body.C] @ u_full - F[body.C]          # force the interface must carry
        u_rec = body.recover(uC_local, F)
        assert np.abs(u_rec - u_full).max() <= 1e-10 * np.abs(u_full).max()
        Fc = body.condensed_load(F)
        R_cond = body.Kc @ uC_local - Fc
        assert np.abs(R_cond - body.R.T @ reaction).max() <= 1e-10 * np.abs(reaction).max()


def test_reduced_stiffness_spd_and_preload_balance(setup):
    m, A, p, rm = setup
    assert np.abs(rm.K - rm.K.T).max() <= 1e-12 * np.abs(rm.K).max()
    assert np.linalg.eigvalsh(rm.K).min() > 0
    lam_w = rm.welded_contact_force([1.0])
    # equilibrium of the top beam: bolt + contact force + clamp reaction = 0
    u1, u2 = rm.recover(np.zeros(rm.K.shape[0]), [1.0])
    top = A[1]
    F = top.loads["preload"]
    clamp = np.zeros(top.n_dofs)
    clamp[top.fixed] = (top.K @ u2 - F)[top.fixed]
    total = (F + clamp).reshape(-1, 2).sum(axis=0) + lam_w.sum(axis=0)
    bolt = abs(F.reshape(-1, 2).sum(axis=0)[1])
    assert np.abs(total).max() < 1e-9 * bolt
    assert lam_w.sum(axis=0)[1] == pytest.approx(bolt, rel=1e-5)  # clamp carries little


def test_modal_projection_equals_phi_M_x_of_recovered_field(setup):
    m, A, p, rm = setup
    md = linear_modes(m, A, p, n_modes=1)
    off = m.dof_offsets()
    Mphi = [a.M @ md.shapes[off[k]:off[k + 1], 0] for k, a in enumerate(A)]
    rm2 = rm.add_pattern("modal", *Mphi).with_functionals({"q": tuple(Mphi)})
    rng = np.random.default_rng(2)
    d = rng.normal(size=rm2.K.shape[0]) * 1e-7
    a = np.array([1.0, 37.0])
    u1, u2 = rm2.recover(d, a)
    q_full = Mphi[0] @ u1 + Mphi[1] @ u2
    assert rm2.evaluate("q", d, a) == pytest.approx(q_full, rel=1e-10)


def _two_hex_beams():
    """A small 3D sandwich: two clamped hexahedral beams, pressure on a patch."""
    from qsma.model import Body, Clamp, Interface, Material, Model, Pressure
    from qsma.mesh.generate import structured_mesh
    xs, zs = np.linspace(0, 0.1, 21), np.linspace(0, 0.02, 5)
    steel = Material(200e9, 0.3, 7800.0)
    bodies = []
    for name, y0, top in (("bottom", 0.0, False), ("top", 0.005, True)):
        m = structured_mesh(xs, np.linspace(y0, y0 + 0.005, 4), zs)
        y_if, y_out = (y0, y0 + 0.005) if top else (y0 + 0.005, y0)
        e = 1e-12
        m = m.with_sets(
            node_sets={"clamp": np.flatnonzero(m.points[:, 0] < e)},
            facet_sets={
                "interface": m.boundary_facets_where(
                    lambda p: (np.abs(p[:, 1] - y_if) < e) & (p[:, 0] > 0.05 - e)),
                "bolt": m.boundary_facets_where(
                    lambda p: (np.abs(p[:, 1] - y_out) < e) & (p[:, 0] > 0.07 - e)
                    & (p[:, 0] < 0.08 + e))})
        bodies.append(Body(name, m, steel, clamps=(Clamp("clamp"),),
                           pressures=(Pressure("bolt", 5e6),)))
    return Model(tuple(bodies), Interface("bottom", "interface", "top", "interface"))


def _mortar(model, refine_top=None, slave=None):
    """``model`` with a mortar interface; ``refine_top`` = (nx, ny[, nz]) remeshes the top
    body's grid so that its interface nodes do not match the bottom's."""
    import dataclasses
    if refine_top is not None:
        from qsma.mesh.generate import structured_mesh
        top = model.bodies[1]
        old = top.mesh
        lo, hi = old.points.min(axis=0), old.points.max(axis=0)
        axes = [np.linspace(a, b, n + 1) for a, b, n in zip(lo, hi, refine_top)]
        mesh = structured_mesh(*axes)
        e = 1e-12
        y0 = lo[1]
        mesh = mesh.with_sets(
            node_sets={"clamp": np.flatnonzero(mesh.points[:, 0] < e)},
            facet_sets={
                "interface": mesh.boundary_facets_where(
                    lambda p: (np.abs(p[:, 1] - y0) < e) & (p[:, 0] > 0.05 - e)),
                "bolt": mesh.boundary_facets_where(
                    lambda p: (np.abs(p[:, 1] - hi[1]) < e) & (p[:, 0] > 0.07 - e)
                    & (p[:, 0] < 0.085 + e))})
        top = dataclasses.replace(top, mesh=mesh)
        model = dataclasses.replace(model, bodies=(model.bodies[0], top))
    itf = dataclasses.replace(model.interface, coupling="mortar", slave=slave)
    return dataclasses.replace(model, interface=itf)


@pytest.mark.parametrize("build", [
    lambda: sandwich_2d(1), _two_hex_beams,
    lambda: _mortar(sandwich_2d(1)),
    lambda: _mortar(_two_hex_beams(), (28, 3, 3)),
    lambda: _mortar(_two_hex_beams(), (28, 3, 3), slave="top"),
], ids=["sandwich-2d", "hex-beams-3d", "sandwich-2d-mortar", "hex-beams-3d-nonmatching",
        "hex-beams-3d-nonmatching-slave-2"])
def test_welded_interface_equals_full_tied_solve(build):
    """d = 0 in the reduced problem is the full two-body model with every pair tied by
    elimination (mortar: slave DOFs = P x master DOFs): displacements and interface
    forces to 1e-9 relative."""
    m = build()
    A = [assemble_body(b) for b in m.bodies]
    p = make_pairing(m)
    rm = reduce_two_bodies(A[0], A[1], p)
    T = tie_transform(m, A, p, np.ones(p.n_pairs, bool))
    K = (T.T @ stacked([a.K for a in A]) @ T).tocsc()
    F = np.concatenate([a.loads["preload"] for a in A])
    x = T @ spla.spsolve(K, T.T @ F)
    u1, u2 = rm.recover(np.zeros(rm.K.shape[0]), [1.0])
    off = m.dof_offsets()
    scale = np.abs(x).max()
    assert np.abs(x[:off[1]] - u1).max() < 1e-9 * scale
    assert np.abs(x[off[1]:] - u2).max() < 1e-9 * scale
    # the force body 2 receives from body 1 through the ties, in the pair frames (mortar
    # with body 1 as master: body 2 is the slave and receives lam at its nodes)
    if p.coupling == "mortar" and p.slave == 1:
        r1 = A[0].K @ x[:off[1]] - A[0].loads["preload"]
        r2 = -r1
        nodes = p.nodes1
    else:
        r2 = A[1].K @ x[off[1]:] - A[1].loads.get("preload", np.zeros(A[1].n_dofs))
        nodes = p.nodes2
    lam_full = np.stack([r2[m.dim * nodes + c] for c in range(m.dim)], axis=1)
    lam_local = np.einsum("pij,pj->pi", p.frames, lam_full)     # rows: (t, n) / (t1, t2, n)
    lam_w = rm.welded_contact_force([1.0])
    assert np.abs(lam_local - lam_w).max() < 1e-9 * np.abs(lam_w).max()
    assert np.linalg.eigvalsh(rm.K).min() > 0


@pytest.mark.parametrize("slave", ["bottom", "top"])
def test_functionals_and_recovery_exact_with_a_nonmatching_interface(slave):
    """Mortar coupling, non-matching 3D beams: the modal amplitude evaluated from (d, a)
    equals phi^T M x of the recovered full fields, and the recovered fields satisfy each
    body's equilibrium with the contact forces -P^T lam / lam (slave) to round-off."""
    m = _mortar(_two_hex_beams(), (28, 3, 3), slave=slave)
    A = [assemble_body(b) for b in m.bodies]
    p = make_pairing(m)
    rm = reduce_two_bodies(A[0], A[1], p)
    md = linear_modes(m, A, p, n_modes=1)
    off = m.dof_offsets()
    Mphi = [a.M @ md.shapes[off[k]:off[k + 1], 0] for k, a in enumerate(A)]
    rm2 = rm.add_pattern("modal", *Mphi).with_functionals({"q": tuple(Mphi)})
    rng = np.random.default_rng(3)
    d = rng.normal(size=rm2.K.shape[0]) * 1e-8
    a = np.array([1.0, 5.0])
    u = rm2.recover(d, a)
    assert rm2.evaluate("q", d, a) == pytest.approx(Mphi[0] @ u[0] + Mphi[1] @ u[1],
                                                    rel=1e-10)
    lam = (rm2.K @ d + rm2.W @ a).reshape(-1, m.dim)
    lam_glob = np.einsum("pji,pj->pi", p.frames, lam)            # frames rows: local axes
    s = p.slave - 1
    sigma = 1.0 if s == 1 else -1.0
    for k, a_ in enumerate(A):
        F = rm2.loads[k] @ a
        r = (a_.K @ u[k] - F).reshape(-1, m.dim)
        expect = np.zeros_like(r)
        if k == s:
            expect[p.contact_nodes] = sigma * lam_glob
        else:
            expect[p.master_nodes] = -sigma * (p.projection.T @ lam_glob)
        free = np.ones(a_.n_dofs, bool)
        free[a_.fixed] = False
        scale = np.abs(lam_glob).max()
        assert np.abs((r - expect).ravel()[free]).max() < 1e-8 * scale


def _random_spd(n, scale, rng):
    B = rng.normal(size=(n, n))
    return scale * (B @ B.T / n + 0.1 * np.eye(n))


@pytest.mark.parametrize("ratio", [1.0, 1e-6])
def test_cholesky_combination_equals_the_direct_formula(ratio):
    """K = Kc_1 (Kc_1 + Kc_2)^-1 Kc_2 written as Kc - Y^T Y agrees with the direct
    product to round-off, also for bodies of very different stiffness."""
    import scipy.linalg as sla
    from qsma.reduction.two_bodies import minus_gram
    rng = np.random.default_rng(4)
    Kc1, Kc2 = _random_spd(60, 1.0, rng), _random_spd(60, ratio, rng)
    S_cho = sla.cho_factor(Kc1 + Kc2)
    direct = Kc1 @ sla.cho_solve(S_cho, Kc2)
    direct = 0.5 * (direct + direct.T)
    soft = Kc2 if ratio < 1 else Kc1
    K = minus_gram(soft, S_cho, soft)
    np.testing.assert_array_equal(K, K.T)
    assert np.abs(K - direct).max() <= 1e-12 * np.abs(direct).max()
    # a rectangular coupling (mortar form A - B S^-1 B^T)
    B = rng.normal(size=(40, 60))
    ref = Kc1[:40, :40] - B @ sla.cho_solve(S_cho, B.T)
    got = minus_gram(Kc1[:40, :40], S_cho, B)
    assert np.abs(got - ref).max() <= 1e-12 * np.abs(ref).max()


def test_reduced_stiffness_equals_the_direct_formula(setup):
    import scipy.linalg as sla
    m, A, p, rm = setup
    Kc1, Kc2 = rm.bodies[0].Kc, rm.bodies[1].Kc
    direct = Kc1 @ sla.cho_solve(sla.cho_factor(Kc1 + Kc2), Kc2)
    direct = 0.5 * (direct + direct.T)
    assert np.abs(rm.K - direct).max() <= 1e-12 * np.abs(direct).max()


@pytest.mark.parametrize("fraction", [1.0, 0.4])
def test_tied_solver_equals_the_sparse_solve_of_the_tied_assembly(setup, fraction):
    """TiedSolver (condensed bodies, open pairs released on the dense interface) gives
    the displacement of the assembled tied structure under a random load, with every
    pair tied and with 40 % of them (the rest free). Measured: 1.6e-10 of the largest
    displacement with every pair tied, 3.2e-10 with 26 of 65 tied: round-off of the
    two solvers (sparse direct against condensed) on this stiffness."""
    from qsma.reduction.two_bodies import tied_solver
    m, A, p, red = setup
    rng = np.random.default_rng(7)
    tied = rng.random(p.n_pairs) < fraction
    T = tie_transform(m, A, p, tied)
    K = (T.T @ stacked([a.K for a in A]) @ T).tocsc()
    f = rng.standard_normal(T.shape[0])
    x = spla.spsolve(K, T.T @ f)
    off = m.dof_offsets()
    u1, u2 = tied_solver(red, tied)(f[off[0]:off[1]], f[off[1]:off[2]])
    u = np.concatenate([u1, u2])
    assert np.abs(u - T @ x).max() < 1e-9 * np.abs(T @ x).max()


def test_body_with_nothing_inside_is_its_own_condensed_stiffness():
    """Two one-element cubes (CalculiX's changefric deck): every free DOF of each lies on
    the interface, nothing is inside to condense, so the condensed stiffness is
    ``K_CC`` itself (no Schur complement), in the pair frames. The tied static solve
    of the two cubes through the reduced model then equals the solve of the assembled
    tied stiffness (a plain sparse solve, no condensation)."""
    from qsma.analysis import prepare
    from qsma.model import Body, Clamp, Interface, Material, Model
    from qsma.mesh.generate import structured_mesh
    bodies = []
    for name, z0, clamp, face in (("lower", 0.0, "bottom", "top"),
                                  ("upper", 1.0, "top", "bottom")):
        m = structured_mesh(np.array([0.0, 1.0]), np.array([0.0, 1.0]),
                            np.array([z0, z0 + 1.0]))
        at = {"bottom": z0, "top": z0 + 1.0}
        m = m.with_sets(node_sets={"clamp": np.flatnonzero(m.points[:, 2] == at[clamp])},
                        facet_sets={"face": m.boundary_facets_where(
                            lambda p, z=at[face]: p[:, 2] == z)})
        bodies.append(Body(name, m, Material(2e11, 0.3, 7800.0), (Clamp("clamp"),)))
    model = Model(tuple(bodies), Interface("lower", "face", "upper", "face"))
    prep = prepare(model)
    for b, a in zip(prep.reduced.bodies, prep.assembled):
        assert len(b.E) == 0
        R = b.R.toarray()
        K_CC = a.K.tocsr()[b.C][:, b.C].toarray()
        assert np.allclose(np.asarray(b.Kc), R.T @ K_CC @ R, rtol=0, atol=1e-12 * np.abs(K_CC).max())
    # tied solve under a load on the upper cube's face nodes against the full solve
    A, p = prep.assembled, prep.pairing
    T = tie_transform(model, A, p, np.ones(p.n_pairs, bool))
    rng = np.random.default_rng(3)
    off = model.dof_offsets()
    f = rng.standard_normal(off[-1])
    x = T @ spla.spsolve((T.T @ stacked([a.K for a in A]) @ T).tocsc(), T.T @ f)
    from qsma.reduction.two_bodies import tied_solver
    u = np.concatenate(tied_solver(prep.reduced, np.ones(p.n_pairs, bool))(
        f[off[0]:off[1]], f[off[1]:off[2]]))
    assert np.abs(u - x).max() < 1e-9 * np.abs(x).max()

