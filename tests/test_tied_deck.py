"""Tied surfaces of a deck: ``*TIE`` and ``PRESSURE-OVERCLOSURE=TIED`` contact pairs read
as tied interfaces, `qsma init` writing them, their refusals; a deck's *TIE in qsma
and in ccx."""
from __future__ import annotations

import dataclasses
import json
import subprocess

import numpy as np
import pytest

import qsma
from qsma.analysis.config import parse_config, tomllib
from qsma.cli import main
from qsma.deck import read_deck
from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.modal import linear_modes
from qsma.model import make_pairing, write_mesh

from helpers import bodies_in_one_mesh, needs_ccx, split_body

CUT = 0.0762                       # a grid line of sandwich-2d's bottom beam
LEVELS = qsma.Levels.log("tip", 1e-6, 1e-3, 5)

STEPS = """*MATERIAL, NAME=STEEL
*ELASTIC
200e9, 0.285
*DENSITY
6600.
*SOLID SECTION, ELSET=left, MATERIAL=STEEL
1.
*SOLID SECTION, ELSET=right, MATERIAL=STEEL
1.
*SOLID SECTION, ELSET=top, MATERIAL=STEEL
1.
*SURFACE INTERACTION, NAME=JOINT
*FRICTION
0.6
*CONTACT PAIR, INTERACTION=JOINT, TYPE=SURFACE TO SURFACE
top_interface, right_interface
{tie}*BOUNDARY
left_clamp, 1, 2
top_clamp, 1, 2
*STEP
*STATIC
*DSLOAD
right_bolt, P, 17.554e6
top_bolt, P, 17.554e6
*END STEP
"""
TIE = "*TIE, NAME=CUT\nright_cut, left_cut\n"
TIED_PAIR = ("*SURFACE INTERACTION, NAME=GLUE\n*SURFACE BEHAVIOR, "
             "PRESSURE-OVERCLOSURE=TIED\n1e16\n*FRICTION\n0.3, 1e16\n"
             "*CONTACT PAIR, INTERACTION=GLUE, TYPE=SURFACE TO SURFACE\nright_cut, left_cut\n")


def split_bodies():
    m = sandwich_2d(1)
    return (*split_body(m.bodies[0], 0, CUT, ("left", "right")), m.bodies[1])


def tied_deck(path, tie=TIE):
    """sandwich-2d with its bottom beam in two parts ('left' clamped, 'right' in the
    joint) as one deck: the parts tied by ``tie``, the joint a *CONTACT PAIR, mu 0.6."""
    write_mesh(path, bodies_in_one_mesh(split_bodies()))
    path.write_text(path.read_text() + STEPS.format(tie=tie))
    return path


def test_a_tie_is_read_as_a_tied_interface_and_runs_as_one_beam(tmp_path):
    """The *TIE becomes a tied interface (slave its first surface); the deck runs as
    sandwich-2d itself: the same f0, backbone and damping."""
    deck = read_deck(tied_deck(tmp_path / "tie.inp"))
    assert not deck.refusals, deck.refusals
    tied = [t for t in deck.config["interfaces"] if t.get("tied")]
    assert tied == [{"body1": "left", "set1": "left_cut", "body2": "right",
                     "set2": "right_cut", "coupling": "auto", "slave": "right",
                     "tied": True}]
    assert "ADJUST" in "\n".join(map(str, deck.notes))       # nodes are not moved
    model = parse_config(deck.config, base=tmp_path).model
    a = qsma.run(model, levels=LEVELS)
    b = qsma.run(sandwich_2d(1), levels=LEVELS)
    assert a.success and a.f0_hz == pytest.approx(b.f0_hz, rel=1e-9)
    assert np.abs(a.q - b.q).max() <= 1e-7 * np.abs(b.q).max()
    assert np.abs(a.zeta - b.zeta).max() <= 1e-7 * b.zeta.max() and b.zeta.max() > 0


def test_a_tied_contact_pair_is_the_tie(tmp_path):
    """A *CONTACT PAIR of PRESSURE-OVERCLOSURE=TIED is the same tied interface (its
    penalty and friction not used, a note says so)."""
    tie = read_deck(tied_deck(tmp_path / "tie.inp"))
    pair = read_deck(tied_deck(tmp_path / "pair.inp", TIED_PAIR))
    assert not pair.refusals, pair.refusals
    assert pair.config["interfaces"] == tie.config["interfaces"]
    assert "PRESSURE-OVERCLOSURE=TIED" in "\n".join(map(str, pair.notes))


def test_init_writes_the_tie_and_runs_as_the_deck(tmp_path):
    """deck -> qsma run and deck -> qsma init -> qsma run: the same results; the TOML
    says which deck line the tie came from."""
    path = tied_deck(tmp_path / "tie.inp")
    args = ["--levels", "tip:list:1e-5,1e-3", "-q", "--no-plots", "--no-vtu"]
    assert main(["run", str(path), "--out", str(tmp_path / "a"), *args]) == 0
    assert main(["init", str(path), "-o", str(tmp_path / "tie.toml")]) == 0
    text = (tmp_path / "tie.toml").read_text()
    assert "tied = true" in text and "*TIE, NAME=CUT, tie.inp, line" in text
    data = tomllib.loads(text)
    assert [t.get("tied", False) for t in data["interfaces"]] == [False, True]
    assert main(["run", str(tmp_path / "tie.toml"), "--out", str(tmp_path / "b"), *args]) == 0
    a, b = (json.loads((tmp_path / f / "results.json").read_text()) for f in "ab")
    assert a["levels"] == b["levels"] and a["mode"] == b["mode"]


def test_a_cyclic_symmetry_tie_is_refused(tmp_path):
    for tie in ("*TIE, CYCLIC SYMMETRY, NAME=CUT\nright_cut, left_cut\n",
                TIE + "*CYCLIC SYMMETRY MODEL, N=12, TIE=CUT\n"):
        deck = read_deck(tied_deck(tmp_path / "cyclic.inp", tie))
        what = "\n".join(map(str, deck.refusals))
        assert "no cyclic symmetry" in what, what
        assert not any(t.get("tied") for t in deck.config["interfaces"])


@pytest.mark.filterwarnings("ignore::qsma.errors.PartialCoverageWarning")
def test_surfaces_apart_are_refused_with_the_distance_and_the_fix(tmp_path):
    """'right' moved 0.1 of an element away from 'left': the tie's slave points lie
    2.54e-4 m from the master surface, beyond 2.5 % of the element (6.35e-5 m); with
    POSITION TOLERANCE=3e-4 the tie is accepted, held across the gap."""
    left, right, top = split_bodies()
    dx = 0.1 * 0.00254                       # a tenth of the coarse element (2.54 mm)
    moved = dataclasses.replace(right, mesh=dataclasses.replace(
        right.mesh, points=right.mesh.points + [dx, 0.0]))
    path = tmp_path / "apart.inp"
    write_mesh(path, bodies_in_one_mesh((left, moved, top)))
    base = path.read_text()
    path.write_text(base + STEPS.format(tie=TIE))
    with pytest.raises(InputError, match=r"tied interface left.left_cut / right.right_cut: "
                                         r"9 of 9 slave point\(s\) lie farther .* up to "
                                         r"2.540e-04 .*Fix: .*POSITION TOLERANCE"):
        read_deck(path)                      # the probe's tied mode pairs the model
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    path.write_text(base + STEPS.format(tie=TIE.replace("NAME=CUT", "NAME=CUT, POSITION "
                                                        "TOLERANCE=3e-4")))
    deck = read_deck(path)
    assert [t.get("position_tol") for t in deck.config["interfaces"]] == [None, 3e-4]
    pairing = make_pairing(parse_config(deck.config, base=tmp_path).model)
    assert pairing.tied[0].pairing.coupling == "mortar"


def test_a_deck_of_ties_only_runs_linear(tmp_path):
    """A deck whose interfaces are all tied runs, every level elastic, and says so."""
    path = tmp_path / "only.inp"
    write_mesh(path, bodies_in_one_mesh(split_bodies()[:2]))
    steps = STEPS.format(tie=TIE)
    for part in ("*SOLID SECTION, ELSET=top, MATERIAL=STEEL\n1.\n",
                 steps[steps.index("*SURFACE INTERACTION"):steps.index("*TIE")],
                 "top_clamp, 1, 2\n", "top_bolt, P, 17.554e6\n"):
        steps = steps.replace(part, "")
    path.write_text(path.read_text() + steps)
    deck = read_deck(path)
    assert not deck.refusals
    assert "every interface is tied" in "\n".join(map(str, deck.notes))
    args = ["--levels", "tip:list:1e-5,1e-3", "-q", "--no-plots", "--no-vtu"]
    assert main(["run", str(path), "--out", str(tmp_path / "out"), *args]) == 0
    levels = json.loads((tmp_path / "out" / "results.json").read_text())["levels"]
    assert levels["dissipation_method"] == ["elastic", "elastic"]
    assert levels["zeta"] == [0.0, 0.0]


def block_deck(folder, n_bottom, n_top):
    """Two steel blocks 1 x 1 x 0.5 m, one on the other, meshed apart (n x n x 2 C3D8
    each), the top one's lower face tied (*TIE, the top the slave) to the bottom one's
    upper face, the base clamped, a *FREQUENCY step of 3 modes."""
    from qsma.mesh.generate import structured_mesh
    from qsma.model import Body, Material

    def block(z0, n, name):
        m = structured_mesh(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1),
                            np.linspace(z0, z0 + 0.5, 3))
        on = lambda z: (lambda p: np.abs(p[:, 2] - z) < 1e-9)
        return Body(name, m.with_sets(
            node_sets={"base": np.flatnonzero(on(0.0)(m.points))},
            facet_sets={"lower": m.boundary_facets_where(on(z0)),
                        "upper": m.boundary_facets_where(on(z0 + 0.5))}),
            Material(210e9, 0.3, 7800.0))

    path = folder / "blocks.inp"
    write_mesh(path, bodies_in_one_mesh((block(0.0, n_bottom, "bottom"),
                                         block(0.5, n_top, "top"))))
    path.write_text(path.read_text() + """*MATERIAL, NAME=STEEL
*ELASTIC
210e9, 0.3
*DENSITY
7800.
*SOLID SECTION, ELSET=bottom, MATERIAL=STEEL
*SOLID SECTION, ELSET=top, MATERIAL=STEEL
*TIE, NAME=GLUE
top_lower, bottom_upper
*BOUNDARY
bottom_base, 1, 3
*STEP
*FREQUENCY
3
*END STEP
""")
    return path


def _tied_frequencies(path, n=3):
    """qsma's frequencies of the tied structure of a deck, and ccx's."""
    model = parse_config(read_deck(path).config, base=path.parent).model
    modes = linear_modes(model, [assemble_body(b) for b in model.bodies],
                         make_pairing(model), n_modes=n)
    subprocess.run(["ccx", path.stem], cwd=path.parent, capture_output=True, timeout=600,
                   check=True)
    lines = path.with_suffix(".dat").read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if "E I G E N V A L U E   O U T P U T" in line)
    rows = [line.split() for line in lines[k + 1:] if line.split()[:1] in (["1"], ["2"],
                                                                            ["3"])]
    return modes.f_hz[:n], np.array([float(r[3]) for r in rows[:n]])


@needs_ccx
def test_a_tie_against_calculix(tmp_path):
    """The deck's *TIE in qsma and in ccx 2.20 (its multipoint constraints, the *FREQUENCY
    step): with coincident nodes the same tied structure, to ccx's printed digits; meshed
    apart (4 x 4 below, 5 x 5 above, the finer side the slave) the two ties differ as
    two discretisations of one constraint do (qsma's dual mortar projection, ccx's
    interpolation on the triangulated master face), by 3.5e-3, and by 1.4e-3 with both
    meshes twice as fine (8 x 8, 10 x 10)."""
    same, ccx = _tied_frequencies(block_deck(tmp_path, 4, 4))
    np.testing.assert_allclose(same, ccx, rtol=2e-7)
    gaps = []
    for n in ((4, 5), (8, 10)):
        folder = tmp_path / f"{n[0]}"
        folder.mkdir()
        f, ccx = _tied_frequencies(block_deck(folder, *n))
        gaps.append(np.abs(f / ccx - 1).max())
    assert gaps[0] < 5e-3 and gaps[1] < 0.5 * gaps[0], gaps
