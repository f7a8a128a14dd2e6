"""The per-level table is one dataclass (qsma.result.LevelTable): every column carries
its meaning, its physical quantity and how the writers treat it, and the user's
reference (docs/results.md) names each one."""
from dataclasses import fields
from pathlib import Path
import re

import pytest

from qsma.analysis.result import LEVEL_COLUMNS, LEVEL_FIELDS, LevelTable, QSMAResult, level_units
from qsma.units import QUANTITIES

DOCS = Path(__file__).resolve().parents[1] / "docs" / "results.md"


def test_every_column_says_what_it_is_and_its_unit():
    for name, c in LEVEL_COLUMNS.items():
        assert c["doc"].strip(), f"{name}: no doc"
        assert c["quantity"] is None or c["quantity"] in QUANTITIES, name
        assert not (c["optional"] and c["nan_when_flagged"]), name
    assert list(level_units("SI", 3)) == list(LEVEL_FIELDS)
    assert level_units("SI", 3)["f_hz"] == "Hz" and level_units("SI", 2)["dissipation"] == "J/m"


def test_the_result_holds_the_columns_in_their_order():
    assert LEVEL_FIELDS == tuple(f.name for f in fields(LevelTable))
    assert [f.name for f in fields(QSMAResult)][:len(LEVEL_FIELDS)] == list(LEVEL_FIELDS)
    derived = {f.name for f in fields(LevelTable) if not f.init}
    assert derived == {"zeta_structure", "zeta_total", "iterations", "residual"}


def test_the_users_reference_names_every_column():
    text = DOCS.read_text()
    section = text[text.index("### Per level"):text.index("## results.csv")]
    named = set(re.findall(r"`(\w+)`", "\n".join(
        line.split("|")[1] for line in section.splitlines() if line.startswith("| `"))))
    missing = [name for name in LEVEL_FIELDS if name not in named]
    assert not missing, f"docs/results.md has no line for {missing}"


@pytest.mark.parametrize("name", ["f_hz", "zeta", "dissipation", "dissipation_method"])
def test_the_chosen_dissipation_columns_come_from_the_dissipation_record(name):
    """A column of the dissipation is a field or property of the record the run takes
    it from (qsma.analysis.Dissipation.columns)."""
    from qsma.analysis import Dissipation
    assert hasattr(Dissipation, name) or name in Dissipation.__dataclass_fields__
