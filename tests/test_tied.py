"""Tied interfaces (``Interface(tied=True)``): a body cut in two along a plane with
coincident nodes and the two parts tied is the body itself, to round-off, in the tied
modes, the preload, the backbone and the damping; the tied points' forces balance the
rest of the structure; a tied interface takes no friction; a model of tied interfaces
only is refused with the way out."""

import dataclasses

import numpy as np
import pytest

import qsma
from qsma.analysis.config import parse_config
from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.model import Interface, Model, Probe, make_pairing

from helpers import split_body

#: a grid line of sandwich-2d's bottom beam (30 of its 60 coarse elements from the clamp)
CUT = 0.0762
LEVELS = qsma.Levels.log("tip", 1e-6, 1e-3, 6)


def split_sandwich(coupling="auto"):
    """sandwich-2d and the same model with its bottom beam cut at x = CUT into 'left'
    (clamped) and 'right' (the joint's side), the two parts tied."""
    m = sandwich_2d(1)
    bottom, top = m.bodies
    left, right = split_body(bottom, 0, CUT, ("left", "right"))
    split = Model(bodies=(left, right, top), interfaces=(
        Interface("left", "cut", "right", "cut", tied=True, coupling=coupling),
        Interface("right", "interface", "top", "interface")),
        tip=Probe(sets=(("right", "tip"), ("top", "tip")), direction=(0.0, 1.0)), mu=m.mu)
    return m, split


@pytest.fixture(scope="module")
def runs():
    m, split = split_sandwich()
    return qsma.run(m, levels=LEVELS), qsma.run(split, levels=LEVELS)


def test_the_split_beam_tied_is_the_beam(runs):
    """Modes, preload, backbone and damping of the tied parts are the beam's: the tie
    is an exact elimination (d = 0 on its points), not a stiff spring."""
    one, two = runs
    assert one.success and two.success
    assert two.f0_hz == pytest.approx(one.f0_hz, rel=1e-10)
    np.testing.assert_allclose(two.modes.f_hz, one.modes.f_hz, rtol=1e-10)
    lam = one.preload.lam
    assert np.abs(two.preload.lam - lam).max() <= 1e-8 * np.abs(lam).max()
    assert np.array_equal(two.preload.status, one.preload.status)
    assert one.zeta.max() > 1e-4                       # the joint does slip
    for name in ("q", "tip", "f_hz"):
        a, b = getattr(one, name), getattr(two, name)
        assert np.abs(b - a).max() <= 1e-8 * np.abs(a).max(), name
    assert np.abs(two.zeta - one.zeta).max() <= 1e-8 * one.zeta.max()
    assert two.model_info["n_tied_pairs"] == 9 and two.model_info["held_by_joint"] == []
    assert two.model_info["n_pairs"] == one.model_info["n_pairs"]


def test_the_fields_of_the_tied_parts_are_the_beams(runs):
    """The recovered displacements of 'left' and 'right' are the bottom beam's at the
    same points (the last level, where pairs slip)."""
    one, two = runs
    k = one.n_levels - 1
    u_one = one.fields(k)[0].reshape(-1, 2)             # bottom beam
    x_one = one.model.bodies[0].mesh.points
    for body, u in zip(two.model.bodies[:2], two.fields(k)[:2]):
        x = body.mesh.points
        order = [int(np.argmin(np.linalg.norm(x_one - p, axis=1))) for p in x]
        ref = u_one[order]
        assert np.abs(u.reshape(-1, 2) - ref).max() <= 1e-8 * np.abs(u_one).max()


def test_the_tied_forces_are_the_nodal_forces_between_the_parts(runs):
    """At the preload and at the last level, the force of each tied point (on 'right',
    local frame turned into global components) is what the node of 'left' there
    receives from its loads and its own stiffness, with the sign changed:
    ``(K u - F)_node = -lam``; and it differs from the welded force ``W a`` alone."""
    _, two = runs
    red, p = two.reduced, two.pairing.tied[0].pairing
    left = assemble_body(two.model.bodies[0])
    for k in (None, two.n_levels - 1):
        alpha = 0.0 if k is None else two.alpha[k]
        d = two.preload.d if k is None else two.states.d[k]
        a = qsma.analysis.result.load_factors(red, alpha)
        lam = np.einsum("pij,pi->pj", p.frames, red.tied_forces(d, a))
        u = red.recover(d, a)[0]
        residual = (left.K @ u - red.loads[0] @ a).reshape(-1, 2)[p.nodes1]
        assert np.abs(residual + lam).max() <= 1e-9 * np.abs(lam).max()
        assert np.abs(lam).max() > 0


def test_a_mortar_tie_of_matching_meshes_is_the_node_tie():
    """The tie through the mortar projection (identity on matching meshes) gives the
    node-to-node tie's run."""
    _, node = split_sandwich("node")
    _, mortar = split_sandwich("mortar")
    assert make_pairing(mortar).tied[0].pairing.coupling == "mortar"
    a, b = qsma.run(node, levels=LEVELS), qsma.run(mortar, levels=LEVELS)
    assert b.f0_hz == pytest.approx(a.f0_hz, rel=1e-10)
    assert np.abs(b.q - a.q).max() <= 1e-8 * np.abs(a.q).max()
    assert np.abs(b.zeta - a.zeta).max() <= 1e-8 * a.zeta.max()


def test_a_tied_interface_takes_no_friction_law_or_gap():
    for key, value in (("mu", 0.3), ("gap", lambda x: 0 * x[:, 0])):
        with pytest.raises(InputError, match=f"tied interface .* takes no {key}"):
            Interface("a", "s", "b", "t", tied=True, **{key: value})
    with pytest.raises(InputError, match="tied must be true or false"):
        Interface("a", "s", "b", "t", tied="yes")


def test_a_model_of_tied_interfaces_only_runs_linear_every_level_elastic(tmp_path):
    """Nothing can open or slip: every level is elastic, D = zeta = 0 exactly, the
    secant frequency is f0 and the tip the linear tied deflection (to the accuracy of
    the eigen solve), the run says why; its f0 is that of the tied modes, and its files
    are written."""
    from qsma.errors import TiedOnlyWarning
    from qsma.modal import linear_modes
    m, split = split_sandwich()
    only = Model(bodies=split.bodies[:2], interfaces=split.interfaces[:1],
                 tip=Probe(sets=(("right", "tip"),), direction=(0.0, 1.0)))
    with pytest.warns(TiedOnlyWarning, match="every interface is tied"):
        res = qsma.run(only, levels=LEVELS)
    assert res.success and "every interface is tied" in res.message
    assert np.all(res.zeta == 0.0) and np.all(res.dissipation == 0.0)
    assert set(res.dissipation_method) == {"elastic"} and res.loops == {}
    np.testing.assert_allclose(res.f_hz, res.f0_hz, rtol=1e-8)
    np.testing.assert_allclose(res.tip, res.tip_lin, rtol=1e-8)
    np.testing.assert_allclose(res.q, res.alpha / res.omega0 ** 2, rtol=1e-8)
    modes = linear_modes(only, [assemble_body(b) for b in only.bodies], make_pairing(only),
                         n_modes=1)
    assert res.f0_hz == pytest.approx(modes.f_hz[0], rel=1e-10)
    qsma.write_all(res, tmp_path / "out")
    assert (tmp_path / "out" / "report.html").exists()


def test_the_toml_key(tmp_path):
    """``tied = true`` in [[interfaces]] (no mu); a frictional interface without mu is
    refused."""
    m, split = split_sandwich()
    from qsma.mesh.io import write_mesh
    tables = []
    for b in split.bodies:
        write_mesh(tmp_path / f"{b.name}.msh", b.mesh)
        tables.append(dict(name=b.name, mesh=f"{b.name}.msh", E=200e9, nu=0.285,
                           rho=6600.0, clamps=[dict(set=c.set) for c in b.clamps],
                           pressures=[dict(set=p.set, p=p.p) for p in b.pressures]))
    data = dict(bodies=tables, interfaces=[
        dict(body1="left", set1="cut", body2="right", set2="cut", tied=True),
        dict(body1="right", set1="interface", body2="top", set2="interface", mu=0.6)],
        tip=dict(sets=[["right", "tip"], ["top", "tip"]], direction=[0.0, 1.0]))
    model = parse_config(data, base=tmp_path).model
    assert [i.tied for i in model.interfaces] == [True, False] and model.mu == 0.6
    del data["interfaces"][1]["mu"]
    with pytest.raises(InputError, match="missing required key 'mu'.*tied = true"):
        parse_config(data, base=tmp_path)


def test_the_calculix_export_refuses_a_tie(tmp_path):
    from qsma.deck import export_calculix
    _, split = split_sandwich()
    with pytest.raises(InputError, match="interface left.cut / right.cut is tied"):
        export_calculix(split, tmp_path / "x.inp")


def test_a_bolted_joint_beside_a_tie_is_the_bolted_beam():
    """sandwich-2d-bolted (a bolt pretensioned, then locked) with its bottom beam cut
    and tied: the same f0, backbone, damping and bolt force as the beam; the tied
    forces (the locked bolt's force among the loads) are the nodal forces between the
    parts."""
    from qsma.examples.bolted import sandwich_2d_bolted
    m = sandwich_2d_bolted(1)
    left, right = split_body(m.bodies[0], 0, CUT, ("left", "right"))
    bolt = dataclasses.replace(m.bolts[0], body_a="right")
    split = Model(bodies=(left, right, m.bodies[1]), interfaces=(
        Interface("left", "cut", "right", "cut", tied=True),
        Interface("right", "interface", "top", "interface")), bolts=(bolt,),
        tip=Probe(sets=(("right", "tip"), ("top", "tip")), direction=(0.0, 1.0)), mu=m.mu)
    one, two = qsma.run(m, levels=LEVELS), qsma.run(split, levels=LEVELS)
    assert one.success and two.success
    assert two.f0_hz == pytest.approx(one.f0_hz, rel=1e-10)
    assert np.abs(two.q - one.q).max() <= 1e-8 * np.abs(one.q).max()
    assert np.abs(two.zeta - one.zeta).max() <= 1e-8 * one.zeta.max()
    k = two.n_levels - 1
    red, p = two.reduced, two.pairing.tied[0].pairing
    a = qsma.analysis.result.load_factors(red, two.alpha[k])
    d = two.states.d[k]
    assert red.bolt_forces(d, a) == pytest.approx(one.reduced.bolt_forces(one.states.d[k], a),
                                                  rel=1e-9)
    lam = np.einsum("pij,pi->pj", p.frames, red.tied_forces(d, a))
    left_asm = assemble_body(left)
    u = red.recover(d, a)[0]
    full = red.base_factors(d, a)
    residual = (left_asm.K @ u - red.base.loads[0] @ full).reshape(-1, 2)[p.nodes1]
    assert np.abs(residual + lam).max() <= 1e-9 * np.abs(lam).max()


def test_the_fields_show_the_tied_points_stuck_with_their_pressure(runs, tmp_path):
    """The VTU fields of a level hold the tied points' contact pressure (their normal
    force over their area) and their state, stuck."""
    import meshio
    from qsma.contact import STUCK
    _, two = runs
    qsma.write_all(two, tmp_path / "out", plots=False)
    k = two.n_levels - 1
    fields = meshio.read(tmp_path / "out" / f"fields_level{k:02d}.vtu").point_data
    p = two.pairing.tied[0].pairing
    lam = two.reduced.tied_forces(two.states.d[k], qsma.analysis.result.load_factors(
        two.reduced, two.alpha[k]))
    start = two.model.bodies[0].mesh.n_nodes                       # 'right' follows 'left'
    for offset, nodes in ((0, p.nodes1), (start, p.nodes2)):
        assert np.all(fields["contact_state"][offset + nodes] == int(STUCK))
        np.testing.assert_allclose(fields["contact_pressure"][offset + nodes],
                                   lam[:, -1] / p.area, rtol=1e-12)


def test_a_bolted_model_of_ties_only_runs_linear():
    """sandwich-2d-bolted with its joint tied: the bolts are locked over an interface
    without contact points, every level elastic."""
    from qsma.errors import TiedOnlyWarning
    from qsma.examples.bolted import sandwich_2d_bolted
    m = sandwich_2d_bolted(1)
    tied = dataclasses.replace(m, interface=dataclasses.replace(m.interface, tied=True))
    with pytest.warns(TiedOnlyWarning):
        res = qsma.run(tied, levels=LEVELS)
    assert res.success and np.all(res.zeta == 0.0)
    np.testing.assert_allclose(res.f_hz, res.f0_hz, rtol=1e-8)
    a = qsma.analysis.result.load_factors(res.reduced, res.alpha[-1])
    assert res.reduced.bolt_forces(res.states.d[-1], a) == pytest.approx(
        [m.bolts[0].pretension], rel=1e-6)
