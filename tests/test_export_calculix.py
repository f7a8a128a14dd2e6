"""``qsma export --calculix``: a model written as a CalculiX deck of the same QSMA
(:mod:`qsma.deck.calculix`). Without ccx: the deck read back by qsma's own deck reader is
the same model and runs to the same numbers; what CalculiX cannot hold is refused by
name. With ccx (benchmarks/bench_export_calculix.py compares): the tied frequency and
the preload's contact forces equal qsma's."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import qsma
from qsma.cli import main
from qsma.analysis.config import parse_config
from qsma.contact.laws import (ElasticStick, ExponentialPressure, InterfaceLaw,
                               LinearPressure, TabularPressure)
from qsma.deck import CalculixRefusal, calculix_deck, export_calculix, read_deck
from qsma.deck.calculix import PENALTY_FACTOR, _default_penalty
from qsma.errors import InputError
from qsma.examples import lap_2d, lap_2d_bolted, lap_3d, sandwich_2d
from qsma.analysis.levels import Levels
from qsma.model.mass import PointMass
from qsma.model.spring import Spring

from helpers import load_benchmark, needs_ccx



def _with_law(model, law):
    return dataclasses.replace(model, interface=dataclasses.replace(model.interface,
                                                                    law=law))


def _reread(path, deck):
    """The model qsma's deck reader makes of an exported deck."""
    read = read_deck(path)
    assert not read.refusals, read.refusals
    return parse_config(read.config, base=read.source.parent).model


LINEAR = InterfaceLaw(LinearPressure(1e15), ElasticStick(1e15))


@pytest.fixture(scope="module")
def linear_sandwich(tmp_path_factory):
    """sandwich-2d with a linear law (the deck then states qsma's law exactly), its
    deck and the model read back from it."""
    model = _with_law(sandwich_2d(1), LINEAR)
    path = tmp_path_factory.mktemp("export") / "sandwich.inp"
    deck = export_calculix(model, path)
    return model, deck, _reread(path, deck)


def test_deck_read_back_is_the_same_model(linear_sandwich):
    model, _, back = linear_sandwich
    assert [b.name for b in back.bodies] == [b.name for b in model.bodies]
    for a, b in zip(model.bodies, back.bodies):
        assert b.material == a.material
        assert np.abs(b.mesh.points - a.mesh.points).max() < 1e-15
        assert np.array_equal(b.mesh.cells, a.mesh.cells)
        assert np.array_equal(b.clamped_dofs(), a.clamped_dofs())
        (pa,), (pb,) = a.pressures, b.pressures
        assert pb.p == pa.p
        rows = lambda m, s: sorted(map(tuple, np.sort(m.facet_sets[s], axis=1).tolist()))
        assert rows(b.mesh, pb.set) == rows(a.mesh, pa.set)
    itf, it2 = model.interface, back.interface
    assert (it2.body1, it2.body2) == (itf.body1, itf.body2)
    assert (it2.mu if it2.mu is not None else back.mu) == model.mu
    assert it2.law == LINEAR


def test_deck_read_back_runs_to_the_same_backbone(linear_sandwich):
    """Same f0, backbone and dissipation. Not bit for bit: coordinates of more than 20
    characters are written rounded (8.7e-19 m here), which the ill-conditioned contact
    solves and the eigen solver carry to 1e-10 (measured 7.8e-11 in f0, 1.6e-10 in q,
    1.8e-9 in the dissipation)."""
    model, _, back = linear_sandwich
    levels = Levels("alpha", (10.0, 100.0, 400.0))
    a, b = qsma.run(model, levels=levels), qsma.run(back, levels=levels)
    assert a.success and b.success
    assert b.f0_hz == pytest.approx(a.f0_hz, rel=1e-8)
    np.testing.assert_allclose(b.q, a.q, rtol=1e-8)
    np.testing.assert_allclose(b.dissipation, a.dissipation, rtol=1e-6, atol=1e-30)


def test_hard_contact_becomes_the_stated_penalty(tmp_path):
    """qsma's hard law is written as a linear penalty PENALTY_FACTOR E / h (stick slope
    the same), stated in a comment; read back it is that layer."""
    model = lap_2d(1)
    deck = export_calculix(model, tmp_path / "lap.inp")
    K = deck.penalty[0][0]
    assert K == pytest.approx(_default_penalty(model, model.interface))
    h = 1e-3                           # lap-2d refine 1: interface cells 1 mm long
    assert K == pytest.approx(PENALTY_FACTOR * 200e9 / h, rel=1e-9)
    assert f"slope {K:.6g} Pa/m" in deck.text
    back = _reread(tmp_path / "lap.inp", deck).interface.law
    assert back.normal == LinearPressure(float(f"{K:.17g}")) or back.normal.k == \
        pytest.approx(K, rel=1e-13)
    assert back.tangential.k == pytest.approx(K, rel=1e-13)


def test_laws_map_to_calculix_laws():
    model = lap_2d(1)
    exp = calculix_deck(_with_law(model, InterfaceLaw(
        ExponentialPressure(2e-6, 1e7, form="calculix"), ElasticStick(1e13)))).text
    assert "PRESSURE-OVERCLOSURE=EXPONENTIAL\n2e-06, 10000000.0" in exp
    assert "*FRICTION\n0.6, 10000000000000.0" in exp
    tab = calculix_deck(_with_law(model, InterfaceLaw(
        TabularPressure(((0.0, 0.0), (1e6, 1e-7), (3e6, 2e-7)))))).text
    # the last slope (2e13 Pa/m) continued to 1000 times the table's overclosure range
    rows = tab.split("PRESSURE-OVERCLOSURE=TABULAR\n")[1].split("\n*")[0].splitlines()
    (p1, h1), (p2, h2) = [[float(v) for v in r.split(",")] for r in rows[-2:]]
    assert len(rows) == 4 and h2 == pytest.approx(2e-7 + 1e3 * 2e-7)
    assert (p2 - p1) / (h2 - h1) == pytest.approx(2e13, rel=1e-12)


@pytest.mark.parametrize("change, words", [
    (lambda m: _with_law(m, InterfaceLaw(ExponentialPressure(2e-6, 1e7, form="abaqus"))),
     "Abaqus' form"),
    (lambda m: dataclasses.replace(m, interface=dataclasses.replace(
        m.interface, gap=lambda x: 0 * x[:, 0])), "initial gap field"),
    (lambda m: dataclasses.replace(m, bodies=(dataclasses.replace(
        m.bodies[0], masses=(PointMass("probe", 0.1),)),) + m.bodies[1:]),
     "point masses of a 2D body"),
    (lambda m: dataclasses.replace(m, bodies=(dataclasses.replace(
        m.bodies[0], mesh=dataclasses.replace(m.bodies[0].mesh, element="CPE4I")),)
        + m.bodies[1:]), "CPE4I (incompatible modes in 2D)"),
])
def test_what_calculix_cannot_hold_is_refused_by_name(change, words):
    with pytest.raises(CalculixRefusal, match=words.replace("(", r"\(").replace(")", r"\)")):
        calculix_deck(change(lap_2d(1)))


def test_2d_bolts_and_nine_node_cells_are_refused():
    with pytest.raises(CalculixRefusal, match="bolt.* of a 2D model"):
        calculix_deck(lap_2d_bolted(1))
    with pytest.raises(CalculixRefusal, match="quad9 cells.*mesh it with quad8"):
        calculix_deck(sandwich_2d(1, element="quad9"))
    m = lap_2d(1)
    with pytest.raises(CalculixRefusal, match="holds the closed pairs by springs"):
        calculix_deck(_with_law(m, LINEAR), tied=True)


def test_tied_deck_ties_the_pairs_qsma_closes():
    """One *EQUATION per closed contact point and direction (lap-2d: clamps stay off
    the interface), none for the open ones."""
    deck = calculix_deck(lap_2d(1), tied=True)
    closed = int(deck.mode["closed"].sum())
    assert 0 < closed < len(deck.mode["closed"])
    assert deck.tied_text.count("\n*EQUATION\n") == 2 * closed
    assert "*CONTACT PAIR" not in deck.tied_text and "*CONTACT PAIR" in deck.text


def test_springs_and_masses_keep_their_totals():
    m = lap_3d(1)
    top = dataclasses.replace(m.bodies[1], springs=(Spring("bolt", (1e6, 2e7, 3e5)),),
                              masses=(PointMass("probe", 0.05),))
    text = calculix_deck(dataclasses.replace(m, bodies=(m.bodies[0], top))).text
    lines = text.splitlines()
    totals = {}
    for k, line in enumerate(lines):
        if line.startswith("*ELEMENT, TYPE=SPRING1") or line.startswith(
                "*ELEMENT, TYPE=MASS"):
            j = k + 1
            while not lines[j].startswith("*"):
                j += 1
            n = j - k - 1
            value_at = j + (2 if "SPRING1" in line else 1)
            key = ("mass",) if "MASS" in line else ("spring", lines[j + 1])
            totals[key] = totals.get(key, 0.0) + n * float(lines[value_at])
    assert totals[("mass",)] == pytest.approx(0.05, rel=1e-12)
    for c, k in enumerate((1e6, 2e7, 3e5)):
        assert totals[("spring", str(c + 1))] == pytest.approx(k, rel=1e-12)


def test_cli_writes_the_deck_and_refuses(tmp_path, capsys):
    out = tmp_path / "lap.inp"
    assert main(["export", "--calculix", str(out), "--example", "lap-2d", "--tied"]) == 0
    assert out.exists() and (tmp_path / "lap-tied.inp").exists()
    assert main(["export", "--calculix", str(out), "--example", "lap-2d"]) == 2   # exists
    assert main(["export", "--calculix", str(tmp_path / "b.inp"), "--example",
                 "lap-2d-bolted"]) == 2
    assert "bolt" in capsys.readouterr().err
    assert main(["export", "--calculix", str(tmp_path / "no" / "x.inp"), "--example",
                 "lap-2d"]) == 2
    assert main(["export", "--calculix", str(tmp_path / "c.inp"), "--example", "lap-2d",
                 "--amplitudes", "tip:list:1e-5", "--cycles", "1"]) == 2
    assert "cycles must be an integer of at least 2" in capsys.readouterr().err
    assert main(["export", "--calculix", str(tmp_path / "c.inp"), "--example", "lap-2d",
                 "--amplitudes", "tip:list:1e-5", "--cycles", "3", "--steps", "2"]) == 0
    assert (tmp_path / "c.inp").read_text().count("*CLOAD") == 1 + 2 * 3


def _cloads(text):
    """Per ``*CLOAD`` card of ``text``: its rows as ``{(node, dof): value}``."""
    out = []
    for block in text.split("*CLOAD\n")[1:]:
        rows = {}
        for line in block.splitlines():
            if line.startswith("*"):
                break
            node, dof, value = line.split(",")
            rows[int(node), int(dof)] = float(value)
        out.append(rows)
    return out


def test_cyclic_steps_carry_the_modal_load():
    """Per amplitude a ramp 0 -> +A and two cycles +A -> -A -> +A by default (the last
    is compared with qsma's stabilised loop); the nodal forces of a step are alpha M phi
    of qsma's mass-normalised mode (phi^T M phi = 1 summed over the bodies)."""
    deck = calculix_deck(lap_2d(1), amplitudes=(2.0, 5.0), steps=4)
    assert deck.cycles == 2 and deck.text.count("*CLOAD") == 2 * (1 + 2 * 2)
    assert "*FREQUENCY" not in deck.text
    norm = sum(np.sum(p * mp) for p, mp in zip(deck.mode["phi"], deck.mode["mphi"]))
    assert norm == pytest.approx(1.0, rel=1e-9)
    # the targets of the steps: +A, then -A, +A per cycle; the forces are alpha M phi
    node, dof = max(_cloads(deck.text)[0].items(), key=lambda kv: abs(kv[1]))[0]
    unit = _cloads(deck.text)[0][node, dof] / 2.0
    targets = [rows[node, dof] / unit for rows in _cloads(deck.text)]
    np.testing.assert_allclose(targets, [2, -2, 2, -2, 2, 5, -5, 5, -5, 5], rtol=1e-12)
    k = deck.first_node.index(max(n for n in deck.first_node if n <= node))
    assert unit == pytest.approx(deck.mode["mphi"][k][node - deck.first_node[k], dof - 1],
                                 rel=1e-12)
    three = calculix_deck(lap_2d(1), amplitudes=(2.0,), steps=4, cycles=3)
    assert three.cycles == 3 and three.text.count("*CLOAD") == 1 + 2 * 3
    assert "cycle 3 of 3" in three.text
    with pytest.raises(InputError, match="increase strictly"):
        calculix_deck(lap_2d(1), amplitudes=(5.0, 2.0))
    for bad in (1, 0, 2.5, True):
        with pytest.raises(InputError, match="cycles must be an integer of at least 2"):
            calculix_deck(lap_2d(1), amplitudes=(2.0,), cycles=bad)


# --- with CalculiX -------------------------------------------------------------------
@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bench_export_calculix")


@needs_ccx
@pytest.mark.parametrize("make", [sandwich_2d, lap_3d], ids=["sandwich-2d", "lap-3d"])
def test_calculix_agrees_on_tied_frequency_and_preload(make, bench, tmp_path):
    """The tied deck's f0 equals qsma's to the 7 digits CalculiX prints (measured
    3.6e-8 and 1.8e-8); the preload's nodal contact forces equal qsma's to the penalty
    (PENALTY_FACTOR = 1e4: measured 4.9e-6 and 8.3e-6 of the largest force, 4.8e-5 at
    1e3), their sums to 1e-6. CalculiX's own perturbation step adds the preload's stress
    stiffness (measured -1.8e-4 and +4.4e-4; it scales with the preload)."""
    r = bench.compare(make(1), tmp_path)
    assert r["f0_tied"] == pytest.approx(r["f0_qsma"], rel=1e-6)
    assert r["max_diff"] < 5e-5
    assert r["total_ccx"] == pytest.approx(r["total_qsma"], rel=1e-5)
    assert r["f0_ccx"] == pytest.approx(r["f0_qsma"], rel=1e-3)


def _dat(times_u):
    """CalculiX's .dat text of one printed node: a displacement block per ``(time,
    u_x)``."""
    return "".join(f"\n displacements (vx,vy,vz) for set NALL and time  {t:.7E}\n\n"
                   f"         1  {u:.6E}  0.000000E+00  0.000000E+00\n"
                   for t, u in times_u)


def test_cycle_dissipations_read_each_cycle_of_the_printed_increments():
    """One node, M phi = (1, 0): q is u_x less its preload value. Two increments per
    branch, A = 2, two cycles whose (q, alpha) polygons enclose 2.8 and 2.4 (shoelace
    formula by hand); the ramp 0 -> +A is no part of either. Output that stops before
    the last step is refused."""
    from qsma.deck.calculix import CalculixDeck
    from qsma.deck.calculix_output import CalculixError, cycle_dissipations
    deck = CalculixDeck("", (1, 2), (1, 2), (), amplitudes=(2.0,), steps=2, cycles=2,
                        mode={"mphi": [np.array([[1.0, 0.0]])]})
    u_pre = 0.3
    q = [0.5, 1.0, 0.8, -1.2, -0.6, 1.0, 0.6, -1.0, -0.6, 1.0]     # at t = 1.5, 2, ..., 6
    text = _dat([(0.5, 0.1), (1.0, u_pre)] + [(1.0 + 0.5 * (k + 1), u_pre + x)
                                              for k, x in enumerate(q)])
    (first, second), = cycle_dissipations(deck, text)
    np.testing.assert_allclose(first[0], [2, 0, -2, 0, 2], atol=1e-12)
    np.testing.assert_allclose(first[1], [1.0, 0.8, -1.2, -0.6, 1.0], atol=1e-12)
    assert first[2] == pytest.approx(2.8, rel=1e-12)
    np.testing.assert_allclose(second[1], [1.0, 0.6, -1.0, -0.6, 1.0], atol=1e-12)
    assert second[2] == pytest.approx(2.4, rel=1e-12)
    with pytest.raises(CalculixError, match="up to time 5 of 6"):
        cycle_dissipations(deck, text.rsplit("\n displacements", 2)[0])


@needs_ccx
def test_calculix_cycles_settle_to_the_loop_qsma_reports(bench, tmp_path):
    """lap-2d with a linear law (2e13 / 1e13 Pa/m, the same in both codes) at a tied tip
    deflection of 1.028e-4 m, where the first cycle after the ramp slips pairs that the
    settled cycles do not (qsma's loop: 2 cycles, a shakedown). CalculiX's three
    cycles of the exported deck (20 increments per branch), measured: 4.4128e-3,
    3.1755e-3, 3.1754e-3 J/m; qsma's stabilised loop 3.1780e-3 +- 8.1e-6 J/m (its first
    cycle 4.3887e-3). The first cycle is 1.39 times the last, the last agrees with qsma
    to 8e-4 (docs/validation.md, "The exported deck's cycles")."""
    law = InterfaceLaw(LinearPressure(2e13), ElasticStick(1e13))
    r = bench.compare(_with_law(lap_2d(1), law), tmp_path,
                      amplitudes=Levels("tip", (1.028e-4,)), steps=20, cycles=3)
    first, second, last = r["D_ccx_cycles"][0]
    assert r["D_qsma_first"][0] > 1.2 * r["D_qsma"][0]        # qsma sees the shakedown
    assert first > 1.2 * last                                  # so does CalculiX
    assert second == pytest.approx(last, rel=1e-3)             # and then it settles
    assert last == pytest.approx(r["D_qsma"][0], rel=5e-3)
