"""Congruent bodies share one factorisation (qsma.reduction.congruence,
condensation.congruent_body).

Detection: the two beams of sandwich-2d (mirror in the interface plane), the two
plates of lap-2d (one turned 180 degrees), the same pairs in a rotated global frame
(a reflection / rotation that is not a signed permutation of the axes) and a small
3D pair under a general rotation; refusals for another mesh, material, element,
clamp or interface. Exactness: every product of the shared factor equals the
separate condensation to round-off (the separate computation is the reference).
"""
from dataclasses import replace
import logging
import pickle

import numpy as np
import pytest

from qsma.analysis import prepare
from qsma.reduction.condensation import condense_body, congruent_body
from qsma.reduction.two_bodies import reduce_two_bodies, tied_solver
from qsma.reduction.congruence import (CongruentMatrix, MappedSolver, find_congruence,
                                       solved_together)
from qsma.errors import InputError
from qsma.examples import lap_2d, sandwich_2d
from qsma.fe import assemble_body
from qsma.model import Body, Clamp, Material, make_pairing
from qsma.mesh.generate import box_nodes, structured_mesh
from qsma.modal import linear_modes
from qsma.model.pairing import body_order


def _rel(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / np.abs(b).max())


def _parts(model):
    """Assembled bodies (interface body order) and the node-to-node pairing."""
    pairing = make_pairing(model)
    i1, i2 = body_order(model, pairing)
    return (assemble_body(model.bodies[i1]), assemble_body(model.bodies[i2])), pairing


def _rotation_2d(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def _moved(model, Q, c):
    """The model with every body's nodes moved to ``Q x + c`` (a rigid motion of the
    whole model: the same joint in another global frame)."""
    return replace(model, bodies=tuple(
        replace(b, mesh=replace(b.mesh, points=b.mesh.points @ Q.T + c))
        for b in model.bodies))


def _check_map(cong, asm):
    """``x_B[perm] = Q x_A + c`` and ``Q`` orthogonal."""
    xa, xb = (a.body.mesh.points for a in asm)
    assert np.allclose(cong.Q @ cong.Q.T, np.eye(len(cong.c)), atol=1e-14)
    size = np.linalg.norm(np.ptp(xa, axis=0))
    assert np.abs(xb[cong.perm] - (xa @ cong.Q.T + cong.c)).max() < 1e-12 * size
    assert cong.mismatch <= 1e-12         # measured 5e-15 .. 1.3e-13 (rotated frames)


# ---------------------------------------------------------------------- detection

def test_mirrored_sandwich_beams_are_found_with_the_mirror():
    asm, pairing = _parts(sandwich_2d(1))
    cong = find_congruence(*asm, pairing.nodes1, pairing.nodes2)
    assert cong is not None and cong.is_signed_permutation
    _check_map(cong, asm)
    assert np.linalg.det(cong.Q) == pytest.approx(-1.0)       # a reflection


def test_lap_plates_turned_half_a_turn_are_found():
    asm, pairing = _parts(lap_2d(1))
    cong = find_congruence(*asm, pairing.nodes1, pairing.nodes2)
    assert cong is not None
    _check_map(cong, asm)
    assert np.array_equal(cong.Q, -np.eye(2))                  # rotation by pi


@pytest.mark.parametrize("make, det", [(sandwich_2d, -1.0), (lap_2d, 1.0)])
def test_the_same_pairs_in_a_rotated_global_frame_are_found(make, det):
    """Not axis aligned: the map is ``R Q0 R^T``: for the sandwich a reflection about
    an inclined line (found from the principal axes of the node clouds), for the lap
    joint still the half turn ``-I``."""
    R = _rotation_2d(0.4321)
    asm, pairing = _parts(_moved(make(1), R, np.array([0.3, -1.7])))
    cong = find_congruence(*asm, pairing.nodes1, pairing.nodes2)
    assert cong is not None
    _check_map(cong, asm)
    assert np.linalg.det(cong.Q) == pytest.approx(det)
    if det < 0:
        assert not cong.is_signed_permutation
        assert _rel(cong.Q, R @ np.diag([1.0, -1.0]) @ R.T) < 1e-12


def _block(Q=np.eye(3), clamp_components=None):
    """A 3D block of hexahedra clamped on its face x = 0, its nodes moved to ``Q x``."""
    mesh = structured_mesh(np.linspace(0, 0.4, 5), np.linspace(0, 0.1, 3),
                           np.linspace(0, 0.06, 3))
    x = mesh.points
    mesh = replace(mesh, points=x @ Q.T,
                   node_sets={"clamp": box_nodes(mesh, lambda p: p[:, 0] < 1e-9),
                              "interface": box_nodes(mesh, lambda p: (p[:, 2] > 0.06 - 1e-9)
                                                     & (p[:, 0] > 0.15)),
                              "far": box_nodes(mesh, lambda p: p[:, 0] > 0.4 - 1e-9)})
    return mesh, Clamp("clamp", clamp_components)


def _rotation_3d():
    A = np.random.default_rng(3).standard_normal((3, 3))
    Q, r = np.linalg.qr(A)
    return Q * np.sign(np.diag(r))


def test_a_3d_pair_under_a_general_rotation_is_found_and_its_condensation_matches():
    steel = Material(200e9, 0.3, 7800.0)
    Q = _rotation_3d()
    mesh_a, clamp = _block()
    mesh_b, _ = _block(Q)
    a = assemble_body(Body("a", mesh_a, steel, clamps=(clamp,)))
    b = assemble_body(Body("b", mesh_b, steel, clamps=(clamp,)))
    nodes = mesh_a.nodes("interface")
    cong = find_congruence(a, b, nodes, nodes)
    assert cong is not None and not cong.is_signed_permutation   # Q or Q S, S a
    _check_map(cong, (a, b))                                     # symmetry of the block
    frames = np.broadcast_to(np.eye(3), (len(nodes), 3, 3))
    base = condense_body(a, nodes, frames)
    derived = congruent_body(base, b, nodes, frames, cong)
    alone = condense_body(b, nodes, frames)
    assert isinstance(derived.solve_EE, MappedSolver)
    assert _rel(derived.Kc, alone.Kc) < 1e-12
    F = np.random.default_rng(1).standard_normal((b.n_dofs, 2))
    assert _rel(derived.condensed_load(F), alone.condensed_load(F)) < 1e-11


def test_a_partial_clamp_is_not_carried_by_a_rotation(caplog):
    """Under a rotation that mixes the axes, a clamp of one component is a
    constraint along an inclined direction, not a clamp: refused."""
    steel = Material(200e9, 0.3, 7800.0)
    Q = _rotation_3d()
    mesh_a, clamp = _block(clamp_components=(2,))
    mesh_b, _ = _block(Q)
    a = assemble_body(Body("a", mesh_a, steel, clamps=(clamp,)))
    b = assemble_body(Body("b", mesh_b, steel, clamps=(clamp,)))
    nodes = mesh_a.nodes("interface")
    with caplog.at_level(logging.INFO, logger="qsma"):
        assert find_congruence(a, b, nodes, nodes) is None
    assert "only whole-node clamps" in caplog.text


# ---------------------------------------------------------------------- refusals

def _refused(model, caplog, words, nodes=None):
    asm, pairing = _parts(model)
    n1, n2 = (pairing.nodes1, pairing.nodes2) if nodes is None else nodes(pairing)
    with caplog.at_level(logging.INFO, logger="qsma"):
        assert find_congruence(*asm, n1, n2) is None
    assert words in caplog.text, caplog.text


def _top(model, **changes):
    bodies = list(model.bodies)
    bodies[1] = replace(bodies[1], **changes)
    return replace(model, bodies=tuple(bodies))


def test_another_mesh_is_refused(caplog):
    model = sandwich_2d(1)
    mesh = model.bodies[1].mesh
    points = mesh.points.copy()
    points[points[:, 0].argmax()] += [0.0, 1e-5]           # one node moved
    _refused(_top(model, mesh=replace(mesh, points=points)), caplog,
             "no orthogonal map of the nodes")


@pytest.mark.parametrize("prop, words", [("E", "the stiffness matrices differ"),
                                         ("rho", "the mass matrices differ")])
def test_another_material_or_density_is_refused(caplog, prop, words):
    model = sandwich_2d(1)
    m = model.bodies[1].material
    changed = replace(m, **{prop: getattr(m, prop) * 1.001})
    _refused(_top(model, material=changed), caplog, words)


def test_another_material_beside_a_stiff_spring_is_refused(caplog):
    """Penalty clamps 1e24 N/m (about 1e13 times the elements' stiffness) on both
    beams and a top beam 1 % stiffer: each entry is checked against its own rows'
    diagonal, so the springs do not hide the material (against the largest entry of
    K, the 1 % difference was 5e-13 of it and the pair was taken as congruent)."""
    from qsma.model import Spring
    model = sandwich_2d(1)
    bodies = tuple(replace(b, clamps=(), springs=(Spring("clamp", (1e24, 1e24)),))
                   for b in model.bodies)
    model = replace(model, bodies=bodies)
    m = bodies[1].material
    _refused(_top(model, material=replace(m, E=m.E * 1.01)), caplog,
             "the stiffness matrices differ")
    asm, pairing = _parts(model)                  # the same springs, the same material
    assert find_congruence(*asm, pairing.nodes1, pairing.nodes2) is not None


def test_another_element_is_refused(caplog):
    model = sandwich_2d(1)
    mesh = model.bodies[1].mesh
    _refused(_top(model, mesh=replace(mesh, element="CPE4I")), caplog,
             "the stiffness matrices differ")


def test_a_clamp_that_does_not_map_is_refused(caplog):
    """The top beam clamped at its free end instead (same number of DOFs)."""
    model = sandwich_2d(1)
    mesh = model.bodies[1].mesh
    far = box_nodes(mesh, lambda p: p[:, 0] > p[:, 0].max() - 1e-12)
    assert len(far) == len(mesh.nodes("clamp"))
    mesh = replace(mesh, node_sets={**mesh.node_sets, "far": far})
    _refused(_top(model, mesh=mesh, clamps=(Clamp("far"),)), caplog,
             "the clamped DOFs do not map")


def test_interface_nodes_that_do_not_map_are_refused(caplog):
    _refused(sandwich_2d(1), caplog, "the interface nodes do not map",
             nodes=lambda p: (p.nodes1, np.arange(len(p.nodes2))))


# ---------------------------------------------------------------------- exactness

@pytest.fixture(scope="module")
def sandwich():
    """sandwich-2d reduced with the shared factor and with two factorisations."""
    model = sandwich_2d(1)
    asm, pairing = _parts(model)
    shared = reduce_two_bodies(*asm, pairing)
    import qsma.reduction.condensation as condensation
    saved = condensation.find_congruence
    condensation.find_congruence = lambda *args: None
    try:
        separate = reduce_two_bodies(*asm, pairing)
    finally:
        condensation.find_congruence = saved
    return model, asm, pairing, shared, separate


def test_the_shared_factor_is_one_object(sandwich):
    _, _, _, shared, separate = sandwich
    b1, b2 = shared.bodies
    assert isinstance(b2.solve_EE, MappedSolver) and b2.solve_EE.base is b1.solve_EE
    assert not isinstance(separate.bodies[1].solve_EE, MappedSolver)


def test_the_congruent_Kc_is_held_implicitly_and_acts_as_the_dense_one(sandwich):
    """Body 2's Kc is body 1's seen through the sparse G: no dense copy of its own,
    products equal those of the dense matrix to round-off."""
    _, _, _, shared, _ = sandwich
    Kc = shared.bodies[1].Kc
    assert isinstance(Kc, CongruentMatrix) and Kc.base is shared.bodies[0].Kc
    assert Kc.nbytes < 0.05 * shared.bodies[0].Kc.nbytes     # G: O(n), not n^2
    dense = np.asarray(Kc)
    assert np.array_equal(dense, dense.T)
    x = np.random.default_rng(8).standard_normal((Kc.shape[0], 3))
    assert _rel(Kc @ x, dense @ x) < 1e-13
    assert _rel(Kc @ x[:, 0], dense @ x[:, 0]) < 1e-13
    assert _rel(x.T @ Kc, x.T @ dense) < 1e-13


def test_condensed_matrices_equal_the_separate_condensation(sandwich):
    _, _, _, shared, separate = sandwich
    assert _rel(shared.bodies[1].Kc, separate.bodies[1].Kc) < 1e-12
    assert np.array_equal(shared.bodies[0].Kc, separate.bodies[0].Kc)
    assert _rel(shared.K, separate.K) < 1e-12
    for f, g in zip(shared.Fc, separate.Fc):
        assert _rel(f, g) < 1e-12
    # W = Kc_2 S^-1 Fc_1 - Kc_1 S^-1 Fc_2 cancels: two separate condensations with
    # other Schur backends (splu, superlu_schur) differ from each other by 1.6e-10
    # relative; the shared factor by 1.5e-10
    assert _rel(shared.W, separate.W) < 1e-9


def test_solves_of_body_2_are_backward_stable_and_equal_its_own_factor(sandwich):
    """Backward error of body 2's solves through body 1's factor at round-off; the
    forward difference from its own factor is that of two factorisations of the
    same matrix (metis_superlu and splu differ by 8.7e-12 on these right-hand sides,
    the shared factor by 2.2e-12: cond(K_EE) times eps)."""
    model, asm, _, shared, separate = sandwich
    b2 = shared.bodies[1]
    s, t = b2.solve_EE, separate.bodies[1].solve_EE
    x = np.random.default_rng(5).standard_normal((s.n, 3))
    K_EE = asm[1].K.tocsr()[b2.E][:, b2.E]
    y = s(x)
    backward = np.abs(K_EE @ y - x).max() / (abs(K_EE).max() * np.abs(y).max())
    assert backward < 1e-14
    assert _rel(y, t(x)) < 1e-10
    assert _rel(s(x[:, 0]), y[:, 0]) < 1e-13
    assert s(x[:, :0]).shape == (s.n, 0)
    with pytest.raises(InputError, match="right-hand side"):
        s(x[:-1])


def test_stacked_solves_equal_the_solves_one_by_one(sandwich):
    _, _, _, shared, _ = sandwich
    b1, b2 = shared.bodies
    rng = np.random.default_rng(2)
    x1, x2 = rng.standard_normal((len(b1.E), 2)), rng.standard_normal(len(b2.E))
    got = solved_together([b1.solve_EE, b2.solve_EE], [x1, x2])
    assert got[0].shape == x1.shape and got[1].shape == x2.shape
    assert _rel(got[0], b1.solve_EE(x1)) < 1e-13
    assert _rel(got[1], b2.solve_EE(x2)) < 1e-13


def test_welded_and_recovered_fields_equal_the_separate_computation(sandwich):
    model, asm, pairing, shared, separate = sandwich
    F = [a.loads["preload"] for a in asm]
    tied = np.ones(pairing.n_pairs, bool)
    tied[::3] = False                                   # some pairs open
    # two separate condensations (other Schur backends) differ by up to 6.6e-11
    # (tied solve) and 4.3e-11 (recovery) relative; the shared factor by 5.0e-11, 1.7e-11
    for u, v in zip(tied_solver(shared, tied)(*F), tied_solver(separate, tied)(*F)):
        assert _rel(u, v) < 3e-10
    d = np.random.default_rng(4).standard_normal(shared.K.shape[0]) * 1e-9
    for u, v in zip(shared.recover(d, [1.0]), separate.recover(d, [1.0])):
        assert _rel(u, v) < 3e-10


def test_tied_modes_equal_the_separate_computation(sandwich):
    model, asm, pairing, shared, separate = sandwich
    a = linear_modes(model, asm, pairing, n_modes=4, reduced=shared)
    b = linear_modes(model, asm, pairing, n_modes=4, reduced=separate)
    assert _rel(a.omega, b.omega) < 3e-11     # Schur backends: 2.5e-12 .. 4.3e-12
    for k in range(4):                         # apart, the shared factor 5.8e-12
        sign = np.sign(a.shapes[:, k] @ b.shapes[:, k])
        assert _rel(sign * a.shapes[:, k], b.shapes[:, k]) < 1e-9


def test_sweep_ships_the_shared_factor_once():
    """A shipped preparation refactorises body 1 only; body 2 solves through it."""
    from qsma.reduction.condensation import RefactorisedEE
    prep = prepare(sandwich_2d(1))
    back = pickle.loads(pickle.dumps(prep))
    b1, b2 = back.reduced.bodies
    assert isinstance(b1.solve_EE, RefactorisedEE)
    assert isinstance(b2.solve_EE, MappedSolver) and b2.solve_EE.base is b1.solve_EE
    x = np.random.default_rng(6).standard_normal(b2.solve_EE.n)
    assert _rel(b2.solve_EE(x), prep.reduced.bodies[1].solve_EE(x)) < 1e-11


def test_several_interfaces_share_the_factor_of_congruent_plates():
    """stack-2d: the top plate is the bottom one mirrored (the middle one differs);
    the stacked reduced model equals the one of three separate condensations."""
    import qsma.reduction.condensation as condensation
    from qsma.examples import stack_2d
    from qsma.model.pairing import multi_pairing
    from qsma.reduction.multibody import reduce_model
    model = stack_2d(1)
    pairing = multi_pairing(model)
    asm = [assemble_body(b) for b in model.bodies]
    shared = reduce_model(model, asm, pairing)
    saved = condensation.find_congruence
    condensation.find_congruence = lambda *args: None
    try:
        separate = reduce_model(model, asm, pairing)
    finally:
        condensation.find_congruence = saved
    kinds = [type(b.solve_EE).__name__ for b in shared.bodies]
    assert kinds == ["EESolver", "EESolver", "MappedSolver"]
    assert shared.bodies[2].solve_EE.base is shared.bodies[0].solve_EE
    assert _rel(shared.bodies[2].Kc, separate.bodies[2].Kc) < 1e-12
    assert _rel(shared.K, separate.K) < 1e-11
    assert _rel(shared.W, separate.W) < 1e-9
