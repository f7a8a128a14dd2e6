"""Bolts in Abaqus/CalculiX decks, both directions: ``qsma export --calculix`` writes a
bolt as two distributing couplings, a beam with a pretension section and a spring in
series (:mod:`qsma.deck.calculix_bolts`); the deck reader reads that pattern back as
the same bolt (:mod:`qsma.deck.bolts`); a pretension section that cuts a meshed bolt
is refused with the pattern to write and its ``E A / L``. With ccx: the preload's bolt
forces, contact forces and the tied frequency equal qsma's
(benchmarks/bench_export_calculix.py, ``--example brb-flat lap-3d-bolted``)."""
from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest

import qsma
from qsma.cli import main
from qsma.analysis.config import parse_config
from qsma.contact.laws import ElasticStick, InterfaceLaw, LinearPressure
from qsma.deck import CalculixRefusal, calculix_deck, export_calculix, read_deck
from qsma.deck.calculix_output import eigenfrequencies, run_calculix
from qsma.examples import LAP_3D, brb, lap_2d_bolted, lap_3d, lap_3d_bolted
from qsma.analysis.levels import Levels
from qsma.mesh.facets import facet_normals

from helpers import load_benchmark, needs_ccx


LINEAR = InterfaceLaw(LinearPressure(1e15), ElasticStick(1e15))


def _brb(law=None):
    """The Brake-Reuss beam at its coarse mesh, flat interface, trilinear hexahedra
    (what CalculiX holds as qsma computes it), three bolts."""
    m = brb(1, surfaces="flat", element="hexahedron")
    if law is not None:
        m = dataclasses.replace(m, interface=dataclasses.replace(m.interface, law=law))
    return m


def _reread(path):
    read = read_deck(path)
    assert not read.refusals, read.refusals
    return read, parse_config(read.config, base=read.source.parent).model


@pytest.fixture(scope="module")
def linear_brb(tmp_path_factory):
    """brb with a linear law (the deck then states qsma's law exactly), its deck and
    the model read back from it."""
    model = _brb(LINEAR)
    path = tmp_path_factory.mktemp("bolts") / "brb.inp"
    deck = export_calculix(model, path)
    read, back = _reread(path)
    return model, deck, read, back


def test_the_deck_holds_each_bolt_as_couplings_pretension_and_spring(linear_brb):
    """Per bolt: two DCOUP3D couplings, a B31 with a pretension section, a SPRINGA of
    the bolt's stiffness; the pretensions as *CLOAD in step 1, the pretension nodes
    fixed from step 2 on."""
    model, deck, _, _ = linear_brb
    text = deck.text
    n = len(model.bolts)
    assert n == 3 and text.count("*DISTRIBUTING COUPLING") == 2 * n
    assert len(re.findall(r"\*PRE-TENSION SECTION, ELEMENT=\w+, NODE=\d+", text)) == n
    assert text.count("*ELEMENT, TYPE=SPRINGA") == n
    steps = text.split("*STEP")
    preload, frequency = steps[1], steps[2]
    for bolt, lay in zip(model.bolts, deck.bolts):
        assert f"\n{lay.nodes[3]}, 1, {bolt.pretension!r}\n" in preload
        assert f"\n{lay.nodes[3]}, 1, 1\n" in frequency.split("*BOUNDARY, FIXED")[1]
        spring = text.split(f"*SPRING, ELSET=BOLT_{lay.label}_K\n")[1]
        assert float(spring.split("\n")[1]) == bolt.stiffness
    # the washer weights of qsma: each coupling's weights sum to 1
    block = text.split("*DISTRIBUTING COUPLING, ELSET=BOLT_bolt1_A\n")[1].split("\n*")[0]
    assert sum(float(r.split(",")[1]) for r in block.splitlines()) == pytest.approx(1.0)


def test_deck_bolts_read_back_as_the_same_bolts(linear_brb):
    model, _, read, back = linear_brb
    assert [b.name for b in back.bolts] == [b.name for b in model.bolts]
    for a, b in zip(model.bolts, back.bolts):
        assert (b.body_a, b.body_b) == (a.body_a, a.body_b)
        assert b.pretension == a.pretension and b.stiffness == a.stiffness
        for body, s_a, s_b in ((a.body_a, a.set_a, b.set_a), (a.body_b, a.set_b, b.set_b)):
            rows = lambda m, s: sorted(map(tuple, np.sort(m.facet_sets[s], axis=1).tolist()))
            assert rows(back.body(body).mesh, s_b) == rows(model.body(body).mesh, s_a)
    assert "bolts" in read.config


def test_deck_with_bolts_runs_to_the_same_backbone(linear_brb):
    """The model read back from the deck runs to the same f0, backbone and
    dissipation (the bolts, their washers and the rest of the model read exactly;
    measured identical to the last digit)."""
    model, _, _, back = linear_brb
    levels = Levels("alpha", (10.0, 100.0))
    a, b = qsma.run(model, levels=levels), qsma.run(back, levels=levels)
    assert a.success and b.success
    assert b.f0_hz == pytest.approx(a.f0_hz, rel=1e-10)
    np.testing.assert_allclose(b.q, a.q, rtol=1e-9)
    assert a.dissipation[-1] > 0
    np.testing.assert_allclose(b.dissipation, a.dissipation, rtol=1e-7, atol=1e-30)


def test_init_writes_the_bolts_table(linear_brb, tmp_path):
    _, deck, _, _ = linear_brb
    out = tmp_path / "brb.toml"
    assert main(["init", str(deck.path), "--out", str(out)]) == 0
    text = out.read_text()
    assert text.count("[[bolts]]") == 3
    assert "pretension = 12249.0" in text and "*PRE-TENSION SECTION" in text
    from qsma.analysis.config import load_config
    model = load_config(out).model
    assert [b.stiffness for b in model.bolts] == [b.stiffness for b in _brb().bolts]


def test_element_sets_may_hold_the_connectors(linear_brb, tmp_path):
    """An element set that lists a bolt's coupling and spring elements with the cells
    (a deck's 'all elements' set) reads: the mesh reader leaves the connectors out of
    it instead of calling them undefined."""
    _, deck, _, _ = linear_brb
    lay = deck.bolts[0]
    path = tmp_path / "all.inp"
    path.write_text(deck.text.replace("*STEP", f"*ELSET, ELSET=EVERYTHING\n1, 2, "
                                      f"{lay.elements[0]}, {lay.elements[3]}\n*STEP", 1))
    read, back = _reread(path)
    assert back.bodies[0].mesh.cell_sets["EVERYTHING"].tolist() == [0, 1]
    assert len(back.bolts) == 3


def test_qsma_runs_the_exported_deck_with_its_bolts(linear_brb, tmp_path):
    """``qsma run deck.inp`` of the exported deck: the same f0 and backbone as the
    model it was written from (its bolts read from the deck)."""
    model, deck, _, _ = linear_brb
    out = tmp_path / "out"
    assert main(["run", str(deck.path), "--out", str(out), "--levels",
                 "alpha:list:10,100", "--no-plots"]) == 0
    result = json.loads((out / "results.json").read_text())
    direct = qsma.run(model, levels=Levels("alpha", (10.0, 100.0)))
    assert result["mode"]["f0_hz"] == pytest.approx(direct.f0_hz, rel=1e-10)
    np.testing.assert_allclose(result["levels"]["q"], direct.q, rtol=1e-9)


def test_2d_bolts_are_refused_for_calculix():
    with pytest.raises(CalculixRefusal, match="of a 2D model: CalculiX 2.20 expands 2D"):
        calculix_deck(lap_2d_bolted(1))


# --- what the reader refuses, with the way ---------------------------------------------
def _lap_deck(tmp_path, edit):
    """The exported deck of lap-3d-bolted with ``edit`` applied to its text."""
    path = tmp_path / "lap.inp"
    export_calculix(lap_3d_bolted(1), path)
    path.write_text(edit(path.read_text()))
    return read_deck(path)


def test_abaqus_couplings_on_surfaces_read_as_the_same_bolt(tmp_path):
    """``*COUPLING, REF NODE=, SURFACE=`` with ``*DISTRIBUTING`` (Abaqus' distributing
    coupling) instead of CalculiX's ``*DISTRIBUTING COUPLING``: the same bolt, its
    washers the surfaces named."""
    def abaqus(text):
        for end, surface in (("A", "BOTTOM_BOLT"), ("B", "TOP_BOLT")):
            block = re.search(rf"\*ELEMENT, TYPE=DCOUP3D, ELSET=BOLT_bolt_{end}\n\d+, (\d+)\n"
                              rf"\*DISTRIBUTING COUPLING, ELSET=BOLT_bolt_{end}\n"
                              rf"(\d+, [^\n]+\n)+", text)
            text = text.replace(block.group(0), f"*COUPLING, REF NODE={block.group(1)}, "
                                f"SURFACE={surface}, CONSTRAINT NAME=C{end}\n"
                                f"*DISTRIBUTING\n1, 3\n")
        return text
    deck = _lap_deck(tmp_path, abaqus)
    assert "*DISTRIBUTING COUPLING" not in deck.source.read_text()
    assert not deck.refusals
    assert not any("WEIGHTING" in n.what for n in deck.notes)
    cubic = _lap_deck(tmp_path, lambda t: abaqus(t).replace(
        "*DISTRIBUTING\n", "*DISTRIBUTING, WEIGHTING METHOD=CUBIC\n"))
    assert not cubic.refusals and cubic.config["bolts"] == deck.config["bolts"]
    assert sum("WEIGHTING METHOD=CUBIC" in n.what for n in cubic.notes) == 2
    (bolt,) = deck.config["bolts"]
    original = lap_3d_bolted(1).bolts[0]
    assert (bolt["set_a"], bolt["set_b"]) == ("BOTTOM_BOLT", "TOP_BOLT")
    assert (bolt["pretension"], bolt["stiffness"]) == (original.pretension,
                                                       original.stiffness)


def test_coupling_weights_other_than_a_uniform_traction_are_named(tmp_path):
    """qsma spreads a bolt's force as a uniform traction over its washer. The exported
    deck writes those weights (no note); the same deck with weight 1 on every node (a
    uniform force per node, as decks often write) reads as the same bolt with a note
    giving how far the deck's weights are from qsma's, so the difference is not
    silent."""
    assert not any("weights" in n.what for n in _lap_deck(tmp_path, lambda t: t).notes)

    def per_node(text):
        def ones(block):
            head, rows = block.group(1), block.group(2)
            return head + "".join(f"{r.split(',')[0]}, 1.\n" for r in rows.splitlines())
        return re.sub(r"(\*DISTRIBUTING COUPLING, ELSET=BOLT_bolt_[AB]\n)((?:\d+, [^\n]+\n)+)",
                      ones, text)
    deck = _lap_deck(tmp_path, per_node)
    assert not deck.refusals
    notes = [n for n in deck.notes if "weights" in n.what]
    assert len(notes) == 2 and all("uniform traction" in n.fix for n in notes)
    gap = float(re.search(r"by up to ([\d.e+-]+) %", notes[0].what).group(1))
    assert gap > 1.0               # the washer's corner nodes carry less than its inner ones
    (bolt,) = deck.config["bolts"]
    assert bolt["pretension"] == lap_3d_bolted(1).bolts[0].pretension


def test_a_bolt_without_its_pretension_load_is_refused(tmp_path):
    deck = _lap_deck(tmp_path, lambda t: re.sub(r"\*CLOAD\n\d+, 1, 8000.0\n", "", t))
    (note,) = deck.refusals
    assert "no *CLOAD on its DOF 1 in the first *STATIC step" in str(note)
    assert "*CLOAD, node, 1, N0" in note.fix


def test_a_prescribed_pretension_is_refused(tmp_path):
    deck = _lap_deck(tmp_path, lambda t: re.sub(r"\*CLOAD\n(\d+), 1, 8000.0\n",
                                                r"*BOUNDARY\n\1, 1, 1, 1e-6\n", t))
    assert any("force controlled" in n.fix for n in deck.refusals)


def test_couplings_of_no_bolt_are_refused_with_the_pattern(tmp_path):
    """Without its member the bolt's couplings belong to no bolt: each is refused by
    line with the pattern of a bolt; a kinematic coupling says what to use instead."""
    def no_member(text):
        text = re.sub(r"\*ELEMENT, TYPE=B31, ELSET=bolt\n[^\n]+\n", "", text)
        return re.sub(r"\*PRE-TENSION SECTION[^\n]*\n[^\n]+\n", "", text)
    deck = _lap_deck(tmp_path, no_member)
    couplings = [n for n in deck.refusals if n.what == "*DISTRIBUTING COUPLING"]
    assert len(couplings) == 2
    assert "two distributing couplings on washer faces of two bodies" in couplings[0].fix
    kinematic = _lap_deck(tmp_path, lambda t: t.replace(
        "*STEP", "*COUPLING, REF NODE=1, SURFACE=TOP_BOLT, CONSTRAINT NAME=C\n*KINEMATIC"
        "\n1, 3\n*STEP", 1))
    (note,) = [n for n in kinematic.refusals if n.what == "*KINEMATIC"]
    assert "qsma has no rigid (kinematic) couplings" in note.fix


def _connector(load="8000.", elasticity="*CONNECTOR ELASTICITY, COMPONENT=1\n1e9\n",
               kind="AXIAL", after=""):
    """The exported lap-3d-bolted deck with its bolt written as Abaqus' connector bolt:
    the beam, its pretension section, the spring and the ties replaced by a CONN3D2
    between the couplings' reference nodes; ``after``: cards of a second step."""
    def edit(text):
        ref_a = re.search(r"TYPE=DCOUP3D, ELSET=BOLT_bolt_A\n\d+, (\d+)\n", text).group(1)
        ref_b = re.search(r"TYPE=DCOUP3D, ELSET=BOLT_bolt_B\n\d+, (\d+)\n", text).group(1)
        member = re.search(r"\*ELEMENT, TYPE=B31, ELSET=bolt\n.*?(?=\*\* body)", text,
                           re.S).group(0)
        text = text.replace(member, f"*ELEMENT, TYPE=CONN3D2, ELSET=bolt\n99001, {ref_a}, "
                            f"{ref_b}\n*CONNECTOR SECTION, ELSET=bolt, BEHAVIOR=BOLTB\n"
                            f"{kind}\n*CONNECTOR BEHAVIOR, NAME=BOLTB\n{elasticity}")
        text = re.sub(r"\*CLOAD\n\d+, 1, 8000.0\n",
                      f"*CONNECTOR LOAD\nbolt, 1, {load}\n", text)
        text = re.sub(r"\*BOUNDARY, FIXED\n\d+, 1, 1\n", after, text)
        return text
    return edit


@pytest.mark.parametrize("load", ["8000.", "-8000."])
def test_an_abaqus_connector_bolt_reads_as_the_same_bolt(tmp_path, load):
    """Abaqus' connector bolt (an AXIAL CONN3D2 between the couplings' reference nodes,
    *CONNECTOR ELASTICITY the stiffness, *CONNECTOR LOAD the pretension): the bolt of
    the model the deck was written from; the tension is the load's magnitude whichever
    sign the deck gives it, which the bolt's comment says."""
    deck = _lap_deck(tmp_path, _connector(load=load))
    assert not deck.refusals, deck.refusals
    (bolt,) = deck.config["bolts"]
    original = lap_3d_bolted(1).bolts[0]
    assert (bolt["pretension"], bolt["stiffness"]) == (original.pretension,
                                                       original.stiffness)
    assert (bolt["body_a"], bolt["body_b"]) == ("bottom", "top")
    assert "magnitude of its *CONNECTOR LOAD" in deck.comments[("bolts", 0)]
    assert not any("CONNECTOR" in n.what for n in deck.notes)


def test_a_connector_held_after_the_preload_is_read_with_a_note(tmp_path):
    """*CONNECTOR MOTION in the step after the preload: Abaqus holds the bolt rigid
    there; qsma keeps the elasticity and says so (not a refusal)."""
    deck = _lap_deck(tmp_path, _connector(after="*CONNECTOR MOTION, FIXED\nbolt, 1\n"))
    assert not deck.refusals
    (note,) = [n for n in deck.notes if "*CONNECTOR MOTION" in n.what]
    assert "keeps the stiffness of its *CONNECTOR ELASTICITY" in note.fix


@pytest.mark.parametrize("edit, says", [
    (dict(kind="BEAM"), "of type BEAM"),
    (dict(elasticity=""), "no positive *CONNECTOR ELASTICITY"),
    (dict(elasticity="*CONNECTOR ELASTICITY, COMPONENT=1, RIGID\n"), "is not linear"),
    (dict(load="0."), "no *CONNECTOR LOAD on its component 1"),
])
def test_a_connector_that_is_no_bolt_is_refused_with_the_pattern(tmp_path, edit, says):
    deck = _lap_deck(tmp_path, _connector(**edit))
    assert "bolts" not in deck.config
    note = next(n for n in deck.refusals if says in n.what)
    assert "CONN3D2" in note.fix or "*CONNECTOR LOAD" in note.fix or \
        "stiffness" in note.fix


@pytest.mark.parametrize("member", ["B31", "T3D2"])
def test_a_member_alone_is_a_bolt_of_its_own_stiffness(tmp_path, member):
    """Abaqus' pattern (the member carries the pretension and the stiffness): a B31
    beam or a T3D2 truss from coupling to coupling, no spring; its E A / L is the
    bolt's stiffness (the section written is a square shank of E A / L = k over the
    bolt's length: the bolt's own k), with a note that CalculiX would hold it rigid."""
    def member_alone(text):
        beam = re.search(r"\*ELEMENT, TYPE=B31, ELSET=bolt\n(\d+), (\d+), (\d+)\n", text)
        spring = re.search(r"\*ELEMENT, TYPE=SPRINGA, ELSET=BOLT_bolt_K\n\d+, \d+, (\d+)\n"
                           r"\*SPRING, ELSET=BOLT_bolt_K\n\n[^\n]+\n", text)
        text = text.replace(beam.group(0), f"*ELEMENT, TYPE={member}, ELSET=bolt\n"
                            f"{beam.group(1)}, {beam.group(2)}, {spring.group(1)}\n")
        if member == "T3D2":       # a truss: its area on a solid section
            section = re.search(r"\*BEAM SECTION, ELSET=bolt, MATERIAL=(\w+), SECTION=RECT"
                                r"\n([^,]+), [^\n]+\n[^\n]+\n", text)
            area = float(section.group(2)) ** 2
            text = text.replace(section.group(0), f"*SOLID SECTION, ELSET=bolt, MATERIAL="
                                f"{section.group(1)}\n{area!r}\n")
        return re.sub(r"\*EQUATION\n\d\n[^\n]+\n", "", text.replace(spring.group(0), ""))
    deck = _lap_deck(tmp_path, member_alone)
    assert not deck.refusals
    (bolt,) = deck.config["bolts"]
    assert bolt["name"] == "bolt"
    assert bolt["stiffness"] == pytest.approx(lap_3d_bolted(1).bolts[0].stiffness,
                                              rel=1e-12)
    assert any("CalculiX deletes a beam" in n.fix for n in deck.notes)


def test_a_meshed_bolt_is_refused_with_its_stiffness(tmp_path):
    """A pretension section cutting a meshed solid: refused with the line, the pattern
    to write instead, and E A / L of the cut (here the bolt patch of the bottom plate,
    10 mm x 8 mm at this mesh, through its thickness t = 5 mm: 200e9 * 8e-5 / 5e-3 =
    3.2e9 N/m)."""
    path = tmp_path / "lap.inp"
    export_calculix(lap_3d(1), path)
    text = path.read_text()
    name = "BOTTOM_BOLT"            # the bottom plate's bolt pressure patch
    assert f"*SURFACE, NAME={name}, TYPE=ELEMENT" in text
    text = text.replace("*STEP", f"*PRE-TENSION SECTION, SURFACE={name}, NODE=99999\n"
                        "*STEP", 1)
    path.write_text(text)
    deck = read_deck(path)
    (note,) = [n for n in deck.refusals if "PRE-TENSION" in n.what]
    assert re.match(r"lap\.inp, line \d+", note.where)
    assert "two *DISTRIBUTING COUPLINGs on the washer faces" in note.fix
    bottom = lap_3d(1).bodies[0].mesh
    A = np.linalg.norm(facet_normals(bottom, bottom.facet_sets["bolt"]), axis=1).sum()
    assert A == pytest.approx(0.010 * 0.008)          # the grid lines next to 10 x 10 mm
    k = LAP_3D["E"] * A / LAP_3D["t"]
    assert f"cut area A = {A:.6g}" in note.fix and f"E A / L = {k:.6g}" in note.fix


BAR = """*NODE
1, 0., 0., 0.
2, 1., 0., 0.
3, 1., 1., 0.
4, 0., 1., 0.
5, 0., 0., 1.
6, 1., 0., 1.
7, 1., 1., 1.
8, 0., 1., 1.
9, 0., 0., 2.
10, 1., 0., 2.
11, 1., 1., 2.
12, 0., 1., 2.
*ELEMENT, TYPE=C3D8, ELSET=BOLT
1, 1, 2, 3, 4, 5, 6, 7, 8
2, 5, 6, 7, 8, 9, 10, 11, 12
*MATERIAL, NAME=STEEL
*ELASTIC
210000., 0.3
*DENSITY
7.85e-9
*SOLID SECTION, ELSET=BOLT, MATERIAL=STEEL
*SURFACE, NAME=CUT
1, S2
*PRE-TENSION SECTION, SURFACE=CUT, NODE=99
0., 0., 1.
*STEP
*STATIC
*CLOAD
99, 1, 1000.
*END STEP
"""


def test_a_cut_through_a_meshed_bolt_is_measured(tmp_path):
    """The pretension surface of a meshed bolt lies inside it (here the face between
    the two elements of a 1 x 1 x 2 bar): the mesh reader leaves it out of the facet
    sets instead of refusing the file, the deck reader measures it (A = 1, L = 2,
    E = 210000: E A / L = 105000) and names the pretension's load with it."""
    path = tmp_path / "bar.inp"
    path.write_text(BAR)
    deck = read_deck(path)
    (note,) = [n for n in deck.refusals if "PRE-TENSION" in n.what]
    assert note.where == "bar.inp, line 25"
    assert "cut area A = 1, length along the section normal L = 2, E = 210000: " \
           "stiffness = E A / L = 105000" in note.fix
    assert not any("'99'" in n.what for n in deck.notes)


# --- with CalculiX --------------------------------------------------------------------
@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bench_export_calculix")


@needs_ccx
def test_calculix_agrees_on_bolt_forces_contact_and_tied_frequency(bench, tmp_path):
    """brb (three bolts, free-free): CalculiX's bolt forces at the end of the preload
    equal the pretensions to its printed digits (measured 3.7e-8), the closed pairs are
    the same, the contact forces' sum equal to 1e-6 (measured equal to 6 digits), the
    nodal forces to the penalty (measured 1.3e-5), the tied deck's f0 equal to qsma's
    to 1e-6 (measured 1.3e-7)."""
    r = bench.compare(_brb(), tmp_path)
    np.testing.assert_allclose(r["bolt_ccx"], r["bolt_qsma"], rtol=1e-6)
    assert r["closed_ccx"] == r["closed_qsma"]
    assert r["total_ccx"] == pytest.approx(r["total_qsma"], rel=1e-6)
    assert r["max_diff"] < 5e-5
    assert r["f0_tied"] == pytest.approx(r["f0_qsma"], rel=1e-6)


@needs_ccx
def test_calculix_holds_the_locked_stiffness(tmp_path):
    """The bolts' stiffness is in CalculiX's tied frequency as in qsma's: with k
    times 100 both codes move f0 by the same +5.5e-4 (measured: qsma 198.79277 ->
    198.90220 Hz), each within 1e-6 of the other."""
    out = []
    for factor in (1.0, 100.0):
        m = _brb()
        m = dataclasses.replace(m, bolts=tuple(dataclasses.replace(
            b, stiffness=factor * b.stiffness) for b in m.bolts))
        deck = export_calculix(m, tmp_path / f"k{factor:g}.inp", tied=True)
        f = eigenfrequencies(run_calculix(deck.tied_path))
        elastic = np.sort(f[f > 1e-3 * deck.mode["f0_hz"]])
        out.append((deck.mode["f0_hz"], elastic[0]))
    (q1, c1), (q2, c2) = out
    assert c1 == pytest.approx(q1, rel=1e-6) and c2 == pytest.approx(q2, rel=1e-6)
    assert q2 / q1 - 1 > 100 * 1e-6


@needs_ccx
def test_calculix_slips_in_the_same_pairs_under_the_pretension(bench, tmp_path):
    """The bolted stack at mu = 0.1 slips under its pretension: the same 37 pairs closed
    and the same 12 slipping in both codes (measured), CalculiX's bolt force N0 to
    5e-8 (measured 8000.000375 N), the contact force through the joint N0."""
    model = dataclasses.replace(bench.VARIANTS["stack-3d-bolted"](1), mu=0.1)
    r = bench.compare(model, tmp_path)
    assert r["closed_ccx"] == r["closed_qsma"] == 37
    assert r["slip_ccx"] == r["slip_qsma"] == 12
    np.testing.assert_allclose(r["bolt_ccx"], r["bolt_qsma"], rtol=1e-6)
    assert r["total_ccx"] == pytest.approx(8000.0, rel=1e-6)
