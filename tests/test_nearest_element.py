"""Elements qsma does not implement computed as their nearest one: a body's ``element``
(``C3D8R`` as ``C3D8I``, ``C3D10M`` as ``C3D10``, ...), set by a deck run with a note."""
from __future__ import annotations

import re
import warnings

import pytest

import qsma
from qsma.analysis.config import parse_config
from qsma.analysis.levels import Levels
from qsma.deck import export_calculix, read_deck
from qsma.deck.calculix_output import eigenfrequencies, run_calculix
from qsma.errors import InputError
from qsma.examples import lap_3d
from qsma.fe.formulation import nearest_element

from helpers import needs_ccx


@pytest.mark.parametrize("name, cell_type, nearest", [
    ("C3D8R", "hexahedron", "C3D8I"), ("C3D8RH", "hexahedron", "C3D8I"),
    ("C3D8H", "hexahedron", "C3D8"), ("C3D10M", "tetra10", "C3D10"),
    ("C3D10I", "tetra10", "C3D10"), ("C3D20RH", "hexahedron20", "C3D20R"),
    ("CPS4R", "quad", "CPS4I"), ("C3D8I", "hexahedron", None), ("C3D20R", "hexahedron20",
                                                                None),
    ("CAX4R", "quad", None), ("C3D8T", "hexahedron", None),
])
def test_the_nearest_element_keeps_what_qsma_computes(name, cell_type, nearest):
    found = nearest_element(name, cell_type)
    assert (found and found[0]) == nearest


@pytest.fixture(scope="module")
def decks(tmp_path_factory):
    """lap-3d's deck with its bricks named C3D8R and C3D8I (keys ``lapR``, ``lapI``)."""
    folder = tmp_path_factory.mktemp("nearest")
    export_calculix(lap_3d(1), folder / "lap.inp")
    out = {}
    for stem in ("lap",):
        text = (folder / f"{stem}.inp").read_text()
        for element in ("C3D8R", "C3D8I"):
            out[stem + element[-1]] = folder / f"{stem}_{element}.inp"
            out[stem + element[-1]].write_text(re.sub(r"TYPE=C3D8\b", f"TYPE={element}",
                                                      text))
    return out


def _f0(config, base):
    model = parse_config(config, base=base).model
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return qsma.run(model, levels=Levels("alpha", (1e-3,))).f0_hz


def test_a_c3d8r_deck_runs_as_c3d8i_with_one_note(decks):
    """C3D8R bricks: the deck's bodies get element = "C3D8I", one note for the element
    name (not one per body) that says why and by how much CalculiX's C3D8R differs,
    and the model is the C3D8I deck's (the same f0 to the last digit)."""
    deck = read_deck(decks["lapR"])
    assert not deck.refusals
    assert [b.get("element") for b in deck.config["bodies"]] == ["C3D8I", "C3D8I"]
    (note,) = [n for n in deck.notes if "C3D8R elements" in n.what]
    assert "computed as C3D8I" in note.what and "hourglass" in note.fix
    plain = read_deck(decks["lapI"])
    assert all("element" not in b for b in plain.config["bodies"])
    assert _f0(deck.config, decks["lapR"].parent) == _f0(plain.config,
                                                           decks["lapI"].parent)


@needs_ccx
def test_c3d8i_frequency_equals_calculix(decks):
    """qsma's C3D8I (the deck's C3D8R) against CalculiX's C3D8I on the same lap joint,
    stuck after the preload: f0 to 1e-4 (measured 793.076 against 793.0386 Hz, 4.7e-5;
    CalculiX's C3D8R gives 697.2 Hz)."""
    config = read_deck(decks["lapR"]).config
    f0 = _f0(config, decks["lapR"].parent)
    ccx = eigenfrequencies(run_calculix(decks["lapI"]))[0]
    assert f0 == pytest.approx(ccx, rel=1e-4)


def test_a_toml_body_names_its_element(decks):
    """The TOML's element key: refused names give the key to write; "nearest" is the
    deck's choice; one name for a body of several cell types is refused."""
    config = read_deck(decks["lapR"]).config
    body = config["bodies"][0]
    body["element"] = "C3D8R"
    with pytest.raises(InputError, match=r'element = "C3D8I"'):
        parse_config(config, base=decks["lapR"].parent)
    body["element"] = "nearest"
    model = parse_config(config, base=decks["lapR"].parent).model
    assert model.bodies[0].mesh.element == "C3D8I"
    body["element"] = "C3D10"
    with pytest.raises(InputError, match="has 10 nodes but the mesh cells are"):
        parse_config(config, base=decks["lapR"].parent)
