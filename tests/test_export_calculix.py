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


def test_cyclic_steps_carry_the_modal_load():
    """Three steps per amplitude; the nodal forces of a step are alpha M phi of qsma's
    mass-normalised mode (phi^T M phi = 1 summed over the bodies)."""
    deck = calculix_deck(lap_2d(1), amplitudes=(2.0, 5.0), steps=4)
    assert deck.text.count("*CLOAD") == 6
    assert "*FREQUENCY" not in deck.text
    norm = sum(np.sum(p * mp) for p, mp in zip(deck.mode["phi"], deck.mode["mphi"]))
    assert norm == pytest.approx(1.0, rel=1e-9)
    with pytest.raises(InputError, match="increase strictly"):
        calculix_deck(lap_2d(1), amplitudes=(5.0, 2.0))


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
