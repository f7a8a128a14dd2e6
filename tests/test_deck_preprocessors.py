"""Decks as pre-processors write them, run as they are: an Abaqus/CAE input file
(parts, instances, internal picked sets, element-face surfaces, two materials, a
perturbation frequency step) and a FreeCAD FEM / PrePoMax CalculiX deck (included mesh
files, C3D10, element-face loads, Windows line ends). Each runs to the results of the
same model built through the Python API, or is refused at its line with the way out."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import qsma
from qsma.analysis.config import parse_config
from qsma.analysis.levels import Levels
from qsma.cli import main
from qsma.deck import read_deck
from qsma.mesh.io import read_assembly
from qsma.model import Probe
from helpers import (ALUMINIUM, CAE_STEEL, FREECAD_LAW, PRE_LAP, cae_lap_deck,
                     freecad_lap_deck, needs_ccx)

#: three levels from stuck to partial slip of the lap joints (zeta 1e-3 at the third)
LEVELS = Levels("alpha", (1.0, 10.0, 100.0))


def with_deck_probe(model, deck):
    """``model`` probed where the deck's default probe is (its node of largest modal
    displacement, along its axis)."""
    (body, point), = deck.config["tip"]["points"]
    names = [b.name for b in model.bodies]
    b = model.bodies[names.index(body)]
    k = int(np.argmin(np.linalg.norm(b.mesh.points - point, axis=1)))
    bodies = list(model.bodies)
    bodies[names.index(body)] = dataclasses.replace(
        b, mesh=b.mesh.with_sets(node_sets={"probe": np.array([k])}))
    return dataclasses.replace(model, bodies=tuple(bodies), tip=Probe(
        ((body, "probe"),), tuple(deck.config["tip"]["direction"])))


def assert_same_run(a, b, rtol=1e-9):
    """Two runs of one model: f0, the preload's total contact force and the backbone
    agree to round-off (the placed instances' coordinates differ from the Python
    model's by round-off only)."""
    assert a.success and b.success
    assert a.f0_hz == pytest.approx(b.f0_hz, rel=rtol)
    fa, fb = (r.preload.lam[:, -1].sum() for r in (a, b))
    assert fa == pytest.approx(fb, rel=rtol) and abs(fa) > 0
    np.testing.assert_allclose(a.q, b.q, rtol=rtol)
    np.testing.assert_allclose(a.f_hz, b.f_hz, rtol=rtol)
    np.testing.assert_allclose(a.zeta, b.zeta, rtol=1e-6, atol=1e-9 * b.zeta.max())
    assert b.zeta.max() > 1e-4                         # the last level slips


@pytest.mark.parametrize("three_parts, element", [(False, "C3D8I"), (True, "C3D8I"),
                                                  (False, "C3D10"), (False, "C3D20R")])
def test_cae_lap_joint_runs_as_the_python_model(tmp_path, three_parts, element):
    """Abaqus/CAE's lap joint: each instance takes the material of its part's section
    (aluminium, steel), the supports on internal picked sets are found (ENCASTRE,
    PINNED, rows 1, 1 ... and a prescribed displacement), the loads (*Dsload, *Cload)
    are the preload, NLGEOM=YES is named, ADJUST= read, the perturbation *Frequency
    step is the mode; the run equals the Python model's."""
    model = cae_lap_deck(tmp_path / "lap.inp", three_parts=three_parts, element=element)
    deck = read_deck(tmp_path / "lap.inp")
    assert not deck.refusals, deck.refusals
    bodies = deck.config["bodies"]
    assert [(b["E"], b["nu"], b["rho"]) for b in bodies] == \
        [(m.E, m.nu, m.rho) for m in (ALUMINIUM, CAE_STEEL, CAE_STEEL)[:len(bodies)]]
    assert bodies[0]["clamps"] == [{"set": "_PickedSet5", "dofs": [1, 2, 3]}]
    assert bodies[1]["clamps"] == [{"set": "_PickedSet6", "dofs": [1, 2, 3]}] or \
        [c["dofs"] for c in bodies[1]["clamps"]] == [[1], [2], [3]]
    assert deck.frequency_modes == 10
    text = "\n".join(map(str, deck.notes))
    assert "lap.inp, line" in text and "NLGEOM" in text and "small-displacement" in text
    if three_parts:
        assert deck.config["interfaces"][1]["adjust"] == 0.0     # adjust=0.0: no change
    a = qsma.run(parse_config(deck.config, base=tmp_path).model, levels=LEVELS)
    b = qsma.run(with_deck_probe(model, deck), levels=LEVELS)
    assert_same_run(a, b)


def test_internal_sets_named_by_supports_and_loads_are_sets_of_the_mesh(tmp_path):
    """CAE's picked regions are internal sets: the ones a *Boundary (also ENCASTRE) or
    *Cload names become node sets of the body, the others stay hidden (the section's
    _PickedSet2)."""
    cae_lap_deck(tmp_path / "lap.inp", three_parts=True)
    asm = read_assembly(tmp_path / "lap.inp")
    lower = asm.body_mesh("Lower-1")
    assert {"_PickedSet5", "_PickedSet10"} <= set(lower.node_sets)
    assert len(lower.node_sets["_PickedSet5"]) == 3 * 5          # the end x = 0
    assert "_PickedSet9" in asm.body_mesh("Block-1").node_sets
    assert not any("_PickedSet2" in n for n in asm.file_mesh.node_sets)


def test_cae_default_hexahedron_c3d8r_runs_as_c3d8i(tmp_path):
    """C3D8R (CAE's default hexahedron) is computed as its nearest element C3D8I, named
    per element name; the deck runs as the Python model of C3D8I plates."""
    from qsma.fe.formulation import with_element
    model = cae_lap_deck(tmp_path / "lap.inp", element="C3D8R")
    deck = read_deck(tmp_path / "lap.inp")
    assert not deck.refusals
    assert [b["element"] for b in deck.config["bodies"]] == ["C3D8I", "C3D8I"]
    assert any("C3D8R elements are computed as C3D8I" in n.what for n in deck.notes)
    model = dataclasses.replace(model, bodies=tuple(
        dataclasses.replace(b, mesh=with_element(b.mesh, "C3D8I")) for b in model.bodies))
    a = qsma.run(parse_config(deck.config, base=tmp_path).model, levels=LEVELS)
    b = qsma.run(with_deck_probe(model, deck), levels=LEVELS)
    assert_same_run(a, b)


def test_an_element_computed_neither_as_it_is_nor_as_its_nearest_is_refused(tmp_path,
                                                                            capsys):
    """C3D8T (coupled temperature-displacement) is no element qsma computes, nor has it
    a nearest one: the deck is refused at each part's *Element line, with the way."""
    cae_lap_deck(tmp_path / "lap.inp", element="C3D8T")
    deck = read_deck(tmp_path / "lap.inp")
    lines = (tmp_path / "lap.inp").read_text().splitlines()
    found = [n for n in deck.refusals if "C3D8T" in n.what]
    assert [n.what for n in found] == ["*ELEMENT, TYPE=C3D8T of body 'Lower-1'",
                                       "*ELEMENT, TYPE=C3D8T of body 'Upper-1'"]
    for n in found:
        assert lines[int(n.where.split("line ")[1]) - 1] == "*Element, type=C3D8T"
        assert "C3D8" in n.fix and "Element Type" in n.fix
    assert main(["run", str(tmp_path / "lap.inp"), "--out", str(tmp_path / "o"),
                 "-q"]) == 2
    assert "C3D8T" in capsys.readouterr().err


def test_a_part_with_sections_of_two_materials_is_refused(tmp_path):
    """A part whose sections name two materials cannot be one body: refused at the
    second section's line, with the way (a part per material)."""
    path = tmp_path / "lap.inp"
    cae_lap_deck(path)
    text = path.read_text()
    k = text.index("*End Part", text.index("*Part, name=Upper"))
    text = (text[:k] + "*Elset, elset=Half, generate\n 1, 80, 1\n"
            "*Solid Section, elset=Half, material=Aluminium\n,\n" + text[k:])
    path.write_text(text)
    deck = read_deck(path)
    line = text[:text.index("*Solid Section, elset=Half")].count("\n") + 1
    (note,) = deck.refusals
    assert note.where == f"lap.inp, line {line}"
    assert "part 'Upper'" in note.what and "['ALUMINIUM', 'STEEL']" in note.what
    assert "a part of its own" in note.fix


@pytest.mark.parametrize("writer, levels", [
    (lambda d: cae_lap_deck(d / "lap.inp", three_parts=True), "alpha:list:1,100"),
    (lambda d: freecad_lap_deck(d), "alpha:list:3e3,3e5")], ids=["cae", "freecad"])
def test_deck_and_its_init_toml_run_to_identical_results(tmp_path, writer, levels):
    """qsma run deck.inp and qsma init deck.inp -> qsma run deck.toml: the same
    results.json levels, mode and preload (the FreeCAD deck with its included files)."""
    writer(tmp_path)
    path = tmp_path / "lap.inp"
    args = ["--levels", levels, "-q", "--no-plots", "--no-vtu"]
    assert main(["run", str(path), "--out", str(tmp_path / "a"), *args]) == 0
    assert main(["init", str(path), "-o", str(tmp_path / "lap.toml")]) == 0
    assert main(["run", str(tmp_path / "lap.toml"), "--out", str(tmp_path / "b"),
                 *args]) == 0
    a, b = (json.loads((tmp_path / f / "results.json").read_text()) for f in "ab")
    assert a["levels"] == b["levels"] and a["mode"] == b["mode"]
    assert a["preload"] == b["preload"]


@pytest.mark.parametrize("contact_type", ["SURFACE TO SURFACE", "NODE TO SURFACE"])
def test_freecad_deck_runs_as_the_python_model(tmp_path, contact_type):
    """FreeCAD FEM's deck (included mesh and set files, C3D10, a material element set
    per solid, *DLOAD rows per element face, one *BOUNDARY row per DOF, Windows line
    ends): each solid a body of its material, the LINEAR surface behavior and the
    stick slope its interface law, the units mm-N-s-tonne from the materials, the
    frequency step that is no perturbation step named; the run equals the Python
    model's."""
    path, model = freecad_lap_deck(tmp_path, contact_type=contact_type)
    assert b"\r\n" in path.read_bytes()
    deck = read_deck(path)
    assert not deck.refusals, deck.refusals
    c = deck.config
    assert c["units"] == "mm-N-s-tonne"
    assert [b["name"] for b in c["bodies"]] == ["SolidMaterialSolid", "SolidMaterial001Solid"]
    assert c["interface"]["law"] == FREECAD_LAW and c["interface"]["mu"] == 0.2
    assert c["interface"]["set2"] == "DEPConstraintContact"          # the slave
    assert {p["face"] for p in c["bodies"][0]["pressures"]} == {1}   # its bottom faces
    text = "\n".join(map(str, deck.notes))
    assert "no PERTURBATION step" in text and "*STEP, PERTURBATION" in text
    levels = Levels("alpha", (3e3, 3e4, 3e5))     # modal forces in mm-N-s-tonne units
    a = qsma.run(parse_config(c, base=tmp_path).model, levels=levels)
    b = qsma.run(with_deck_probe(model, deck), levels=levels)
    assert_same_run(a, b)
    assert a.preload.lam[:, -1].sum() == pytest.approx(PRE_LAP["p"] * 1e-4, rel=1e-3)


@needs_ccx
def test_freecad_deck_tied_f0_against_calculix(tmp_path):
    """qsma's f0 of the FreeCAD deck (C3D8I here: linear facets) against ccx 2.20's
    *FREQUENCY on the same deck, converted in two points: the frequency step made a
    PERTURBATION step (else CalculiX computes the modes without the preload's contact),
    and the LINEAR behaviour given a tension of 1e-6 MPa at clearances (CalculiX's
    default tension keeps open pairs near the joint pulling, which qsma's layer does
    not). CalculiX's node-to-surface and surface-to-surface contact put the mode 802.2
    and 780.4 Hz apart (2.8 %, measured): qsma's 795.2 Hz lies between them, 0.9 % and
    1.9 % from each (the contact's discretisation, not its law, makes the spread)."""
    from qsma.deck.calculix_output import eigenfrequencies, run_calculix
    path, _ = freecad_lap_deck(tmp_path, element="C3D8I")
    deck = read_deck(path)
    f0 = qsma.run(parse_config(deck.config, base=tmp_path).model,
                  levels=Levels("alpha", (3e3,))).f0_hz
    text = path.read_bytes().decode()
    k = text.index("** Frequency analysis")
    text = text[:k] + text[k:].replace("*STEP\r\n", "*STEP, PERTURBATION\r\n", 1)
    text = text.replace("1000000.0 \r\n", "1000000.0, 1e-6\r\n", 1)
    f_ccx = []
    for kind in ("NODE TO SURFACE", "SURFACE TO SURFACE"):
        (tmp_path / "ccx.inp").write_bytes(text.replace(
            "TYPE=SURFACE TO SURFACE", f"TYPE={kind}").encode())
        f_ccx.append(eigenfrequencies(run_calculix(tmp_path / "ccx.inp", timeout=300))[0])
    assert min(f_ccx) < f0 < max(f_ccx)
    assert max(abs(f / f0 - 1) for f in f_ccx) < 0.02


def _cae_variant(tmp_path, old, new):
    """The two-plate CAE deck with ``old`` replaced by ``new``, read."""
    path = tmp_path / "lap.inp"
    cae_lap_deck(path)
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new))
    return read_deck(path)


def test_rough_friction_is_no_slip_not_frictionless(tmp_path):
    """*Friction, rough (CAE's 'Rough' tangential behaviour) has no data line: it is no
    slip, qsma's largest mu, named; never the frictionless joint of a missing
    *Friction."""
    deck = _cae_variant(tmp_path, "*Friction\n0.2,\n", "*Friction, rough\n")
    assert deck.config["interface"]["mu"] == 1e4
    assert not deck.refusals
    (note,) = [n for n in deck.notes if "ROUGH" in n.what]
    assert "no slip" in note.what and "frictionless" not in str(note)


def test_no_separation_is_refused(tmp_path):
    deck = _cae_variant(tmp_path, "*Surface Behavior, pressure-overclosure=HARD",
                        "*Surface Behavior, no separation, pressure-overclosure=HARD")
    (note,) = deck.refusals
    assert "NO SEPARATION" in note.what and "allow separation" in note.fix


def test_section_controls_are_harmless(tmp_path):
    deck = _cae_variant(tmp_path, "** MATERIALS", "*Section Controls, name=EC-1, "
                        "hourglass=ENHANCED\n1., 1., 1.\n** MATERIALS")
    assert not deck.refusals
    assert any("SECTION CONTROLS" in n.what for n in deck.notes)


def test_freecad_solids_left_apart_by_a_small_gap(tmp_path):
    """FreeCAD users leave a small gap between solids meshed in one go (touching
    solids would be fused): the 0.01 mm gap is the contact problem's initial gap,
    named by a warning, and the preload closes it under the washer; the run equals
    the Python model's with the same gap."""
    from qsma.errors import InterfaceGapWarning
    path, model = freecad_lap_deck(tmp_path, element="C3D8I", gap=0.01)
    deck = read_deck(path)
    assert not deck.refusals
    levels = Levels("alpha", (3e3, 3e4, 3e5))
    with pytest.warns(InterfaceGapWarning, match="1.000e-02 apart"):
        a = qsma.run(parse_config(deck.config, base=tmp_path).model, levels=levels)
    b = qsma.run(with_deck_probe(model, deck), levels=levels)
    assert_same_run(a, b)
    assert a.preload.lam[:, -1].sum() == pytest.approx(PRE_LAP["p"] * 1e-4, rel=1e-2)


def test_cae_general_contact_runs_as_its_contact_pair(tmp_path):
    """CAE's general contact (*Contact, ALL EXTERIOR, one property) in place of the
    surface-to-surface pair: the touching faces are the overlap, and the run is the
    contact pair deck's."""
    (tmp_path / "pair").mkdir()
    cae_lap_deck(tmp_path / "pair" / "lap.inp")
    pair = read_deck(tmp_path / "pair" / "lap.inp")
    general = _cae_variant(
        tmp_path, "*Contact Pair, interaction=IntProp-1, type=SURFACE TO SURFACE\n"
        "Surf-2, Surf-1\n", "*Contact, op=NEW\n*Contact Inclusions, ALL EXTERIOR\n"
        "*Contact Property Assignment\n ,  , IntProp-1\n")
    assert not general.refusals and general.config["interface"]["touching"]
    a = qsma.run(parse_config(general.config, base=tmp_path).model, levels=LEVELS)
    b = qsma.run(parse_config(pair.config, base=tmp_path / "pair").model, levels=LEVELS)
    assert_same_run(a, b)
