"""Grounded springs (qsma.model.spring; issue 12: the cantilever lap joint with a
spring at the top plate's far end between the free and the clamped plate)."""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

import qsma
from qsma.analysis.config import parse_config, tomllib
from qsma.errors import InputError
from qsma.examples import lap_2d, lap_2d_cantilever
from qsma.fe import assemble_body
from qsma.model import Body, Material, Pressure, Spring
from qsma.mesh.generate import structured_mesh
from qsma.model.spring import spring_matrix, spring_shares
from qsma.examples import example_dir

STEEL = Material(200e9, 0.3, 7850.0)


def _block(springs=(), pressures=(), clamps=()):
    """A 40 x 10 mm block (16 x 4 quads) with its lower face as facet set 'base'
    and its right end as node set 'end'."""
    mesh = structured_mesh(np.linspace(0, 0.04, 17), np.linspace(0, 0.01, 5))
    eps = 1e-12
    mesh = mesh.with_sets(
        node_sets={"end": np.flatnonzero(mesh.points[:, 0] > 0.04 - eps)},
        facet_sets={"base": mesh.boundary_facets_where(lambda p: p[:, 1] < eps),
                    "top": mesh.boundary_facets_where(lambda p: p[:, 1] > 0.01 - eps)})
    return Body("block", mesh, STEEL, clamps=clamps, pressures=pressures, springs=springs)


def test_a_rigid_translation_of_the_set_meets_the_given_stiffness():
    """``K_s`` resists a translation ``t`` of the set with the force ``-k_c t_c``:
    the total stiffness is the set's, whatever the shares."""
    for spring in (Spring("end", (3e6, 5e7)), Spring("base", (2e5, 7e8))):
        body = _block((spring,))
        nodes, shares = spring_shares(body, spring)
        assert shares.sum() == pytest.approx(1.0, rel=1e-14)
        Ks = spring_matrix(body)
        for c in range(2):
            t = np.zeros((body.mesh.n_nodes, 2))
            t[:, c] = 1.0
            assert (Ks @ t.ravel()).sum() == pytest.approx(spring.stiffness[c], rel=1e-14)


def test_shares_are_tributary_on_a_facet_set_and_equal_on_a_node_set():
    """Base face of 16 equal segments: the end nodes carry half a segment (1/32),
    the others one (1/16); the 5 end nodes share equally (1/5)."""
    body = _block()
    _, s = spring_shares(body, Spring("base", (1.0, 1.0)))
    np.testing.assert_allclose(s, [1 / 32] + [1 / 16] * 15 + [1 / 32], rtol=1e-13)
    _, s = spring_shares(body, Spring("end", (1.0, 1.0)))
    np.testing.assert_allclose(s, np.full(5, 0.2), rtol=1e-14)


def test_block_on_an_elastic_foundation_under_its_own_pressure_translates():
    """A free block resting on springs spread over its base (stiffness k_y), loaded by
    a uniform pressure p on the same face: each base node's spring balances its share
    of the pressure, so the block translates rigidly by ``u_y = p A / k_y`` and is not
    strained (analytical, to round-off)."""
    ky, p = 4e9, 2e6                  # the pressure pushes the base up, into the block
    body = _block((Spring("base", (1e9, ky)),), (Pressure("base", p),))
    a = assemble_body(body)
    u = np.linalg.solve(a.K.toarray(), a.loads["preload"]).reshape(-1, 2)
    expected = p * 0.04 / ky          # p A / k_y, A = 40 mm (per metre of depth)
    np.testing.assert_allclose(u[:, 1], expected, rtol=1e-9)
    assert np.abs(u[:, 0]).max() < 1e-9 * abs(expected)


def test_springs_hold_a_body_against_rigid_motion():
    """A body with no clamp, on springs in x and y at one end, is held (its rigid
    motions are not free); springs along y only, spread over the base, leave the x
    translation free, and at the end (one x) the rotation too."""
    from qsma.reduction.rigid import free_motions, held
    held_body = assemble_body(_block((Spring("end", (1e6, 1e6)),)))
    assert free_motions(held_body.body.mesh.points, held(held_body)).shape[1] == 0
    for where, n_free in (("base", 1), ("end", 2)):
        half = assemble_body(_block((Spring(where, (0.0, 1e6)),)))
        assert free_motions(half.body.mesh.points, held(half)).shape[1] == n_free


@pytest.mark.parametrize("stiffness, match", [
    ((-1.0, 1.0), "stiffness must be finite numbers >= 0"),
    ((float("nan"), 1.0), "stiffness must be finite numbers >= 0"),
    ((float("inf"), 1.0), "stiffness must be finite numbers >= 0"),
    (("1e6", 1.0), "stiffness must be finite numbers >= 0"),
    (1e6, "stiffness must be a list of one value per direction"),
])
def test_bad_stiffness_is_refused_by_name(stiffness, match):
    with pytest.raises(InputError, match=f"spring on 'end': {match}"):
        Spring("end", stiffness)


def test_unknown_set_and_wrong_length_are_refused_by_name():
    with pytest.raises(InputError, match="body 'block': spring on unknown set 'tip'"):
        _block((Spring("tip", (1.0, 1.0)),))
    with pytest.raises(InputError, match="body 'block': spring on 'end' needs 2 stiffness"):
        _block((Spring("end", (1.0, 1.0, 1.0)),))


def test_a_set_without_nodes_or_area_is_refused_by_name():
    """An empty node set would divide by zero, a facet set of zero area would spread
    NaN shares into K: both refused when the body is made."""
    mesh = structured_mesh(np.linspace(0, 0.04, 17), np.linspace(0, 0.01, 5))
    flat = np.array([[0, 0]])                          # a facet from node 0 to itself
    mesh = mesh.with_sets(node_sets={"none": np.array([], dtype=int)},
                          facet_sets={"flat": flat})
    with pytest.raises(InputError, match="spring on 'none': the set has no nodes"):
        Body("block", mesh, STEEL, springs=(Spring("none", (1.0, 1.0)),))
    with pytest.raises(InputError, match="spring on 'flat': the facet set has no area"):
        Body("block", mesh, STEEL, springs=(Spring("flat", (1.0, 1.0)),))


EXAMPLES = example_dir()        # the example files shipped with qsma


def test_toml_springs():
    """``springs = [{set, stiffness}]`` in a [[bodies]] table builds the Spring; a
    negative value is refused naming the body."""
    data = tomllib.loads((EXAMPLES / "sandwich-2d.toml").read_text())
    data["bodies"][1]["clamps"] = []
    data["bodies"][1]["springs"] = [{"set": "clamp", "stiffness": [1e7, 2e7]}]
    cfg = parse_config(data, base=EXAMPLES)
    assert cfg.model.bodies[1].springs == (Spring("clamp", (1e7, 2e7)),)
    bad = copy.deepcopy(data)
    bad["bodies"][1]["springs"][0]["stiffness"] = [1e7, -1.0]
    with pytest.raises(InputError, match=r"bodies\[1\] \('top'\): spring on 'clamp': "
                                         r"stiffness must be finite"):
        parse_config(bad, base=EXAMPLES)
    bad["bodies"][1]["springs"][0] = {"set": "clamp"}
    with pytest.raises(InputError, match="missing required key 'stiffness'"):
        parse_config(bad, base=EXAMPLES)


# ---------------------------------------------------------------- the cantilever check
LEVELS = qsma.Levels.log("tip", 1e-5, 1e-3, 5)


@pytest.fixture(scope="module")
def cantilever():
    """The lap-2d cantilever (mu = 0.1): free top plate, clamped top plate, and the top
    plate's far end on springs of 1e3, 1e4, 1e12, 1e14 N/m per m."""
    run = lambda m: qsma.run(m, levels=LEVELS, refine_levels=False)
    out = {"free": run(lap_2d_cantilever(1, mu=0.1)), "clamped": run(lap_2d(1, mu=0.1))}
    for k in (1e3, 1e4, 1e12, 1e14):
        out[k] = run(lap_2d_cantilever(1, mu=0.1, spring=k))
    return out


def test_soft_spring_converges_to_the_free_top_plate(cantilever):
    """As k -> 0 the damping curve converges to that of the top plate held only by the
    joint, linearly in k: measured max |zeta - zeta_free| = 1.30e-5, 1.31e-6, 1.31e-7
    and max |f / f_free - 1| = 3.1e-3, 3.1e-4, 3.1e-5 for k = 1e4, 1e3, 1e2 N/m per
    m (zeta up to 1.0e-3; the plate's own cantilever stiffness is 1.8e7 N/m)."""
    free = cantilever["free"]
    assert free.success and free.model_info["held_by_joint"] == ["top"]
    dz, df = [], []
    for k in (1e4, 1e3):
        r = cantilever[k]
        assert r.success, r.message
        assert r.model_info["held_by_joint"] == []        # the spring holds it
        dz.append(np.abs(r.zeta - free.zeta).max())
        df.append(np.abs(r.f_hz / free.f_hz - 1).max())
    for d in (dz, df):
        assert 8 < d[0] / d[1] < 12                        # linear in k
    assert dz[1] < 2e-6 and df[1] < 5e-4
    assert free.zeta.max() > 5e-4                          # the joint slips


def test_stiff_spring_approaches_the_clamped_top_plate(cantilever):
    """As k -> infinity the curve approaches the clamped top plate's (lap-2d, f0
    844.05 Hz against 148.14 Hz free): measured max |f / f_clamped - 1| = 9.5e-3 and
    1.06e-4, max |zeta - zeta_clamped| = 3.8e-5 and 6.2e-6 for k = 1e12, 1e14 N/m per
    m (zeta up to 5.5e-3)."""
    clamped = cantilever["clamped"]
    df = [np.abs(cantilever[k].f_hz / clamped.f_hz - 1).max() for k in (1e12, 1e14)]
    dz = [np.abs(cantilever[k].zeta - clamped.zeta).max() for k in (1e12, 1e14)]
    assert all(cantilever[k].success for k in (1e12, 1e14))
    assert df[1] < 2e-4 and df[0] / df[1] > 50
    assert dz[1] < 1e-5 and dz[1] < dz[0]
