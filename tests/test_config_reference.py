"""docs/config.md against the reader: every key of every table, its type, whether it is
required, its default, and the complete example file."""
from __future__ import annotations

import dataclasses
from pathlib import Path
import re
import typing

import pytest

from qsma.analysis.config import SCHEMA, parse_config, tomllib
from qsma.model import Interface, Pressure
from qsma.analysis.options import RunOptions
from qsma.examples import example_dir

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "config.md"
#: the sections of docs/config.md: SCHEMA's, "" written "top"; [analysis] is RunOptions
#: and ``modes`` (taken out by the reader)
SECTIONS = {("top" if k == "" else k): v for k, v in SCHEMA.items()}
TYPE_NAMES = {str: "string", int: "integer", list: "list", dict: "table", bool: "boolean"}


def _tables() -> dict:
    """section -> {key: (type, default)} from the tables of docs/config.md."""
    out, names = {}, []
    for line in DOC.read_text().splitlines():
        m = re.fullmatch(r"<!-- table: (\w+) -->", line.strip())
        if m:
            names.append(m.group(1))
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if names and len(cells) == 5 and cells[0].startswith("`"):
            for name in names:
                out.setdefault(name, {})[cells[0].strip("`")] = (cells[1], cells[2])
        elif names and not line.strip().startswith("|") and line.strip() and \
                not line.startswith("<!--") and any(name in out for name in names):
            names = []
    return out


def _type_name(types) -> str:
    if isinstance(types, tuple):
        return "number or string" if str in types else "number"
    return TYPE_NAMES[types]


def _hint_name(hint) -> str:
    """The type column of an [analysis] key from RunOptions' annotation."""
    args = [a for a in typing.get_args(hint) if a is not type(None)] or [hint]
    if hint is typing.Any:
        return "string or integer"
    names = {float: "number", int: "integer", bool: "boolean", str: "string"}
    return names[args[0]]


def test_every_table_of_the_reader_is_documented():
    assert set(_tables()) == set(SECTIONS) | {"analysis"}


@pytest.mark.parametrize("section", sorted(SECTIONS))
def test_keys_types_and_required_match_the_schema(section):
    doc = _tables()[section]
    schema = SECTIONS[section]
    assert set(doc) == set(schema), "docs/config.md and qsma.config.SCHEMA differ"
    for key, (types, required) in schema.items():
        type_name, default = doc[key]
        assert type_name == _type_name(types), key
        assert (default == "required") == required, key


def test_analysis_keys_types_and_defaults_match_run_options():
    doc = _tables()["analysis"]
    hints = RunOptions.table_keys()
    assert set(doc) == set(hints) | {"modes"}
    defaults = {f.name: f.default for f in dataclasses.fields(RunOptions)}
    for key, hint in hints.items():
        type_name, default = doc[key]
        assert type_name == _hint_name(hint), key
        if defaults[key] is None:
            assert default == "(none)", key
        else:
            assert tomllib.loads(f"v = {default.strip('`')}")["v"] == defaults[key], key


def test_literal_defaults_are_the_readers():
    """The defaults written as values outside [analysis] are those the reader applies."""
    doc = _tables()
    assert doc["top"]["name"][1] == '`"model"`'
    assert doc["pressures"]["load"][1] == f'`"{Pressure("s", 1.0).load}"`'
    assert doc["interface"]["coupling"][1] == f'`"{Interface("a", "s", "b", "t").coupling}"`'
    model = parse_config(_example(), base=example_dir()).model
    data = _example()
    data.pop("name")
    assert parse_config(data, base=example_dir()).model.name == "model"
    assert model.name != "model"


def _example() -> dict:
    text = DOC.read_text()
    block = re.search(r"## A complete file.*?```toml\n(.*?)```", text, re.S).group(1)
    return tomllib.loads(block)


def test_the_complete_example_is_read():
    """The example file uses every table and builds the model it describes."""
    data = _example()
    cfg = parse_config(data, base=example_dir())
    used = {"top"} | {k for k in data if isinstance(data[k], (dict, list))}
    for b in data["bodies"]:
        used |= {k for k in b if isinstance(b[k], list)}
    for itf in data["interfaces"]:
        used |= {k for k in itf if isinstance(itf[k], dict)}
    assert used >= set(SECTIONS) - {"interface", "pressures"}   # bolts instead of pressures
    assert cfg.modes == (0, 1) and len(cfg.model.bolts) == 1
    assert cfg.model.bodies[1].masses[0].mass == 0.05
    assert cfg.model.bodies[0].clamps[0].components == (0, 1)
    assert cfg.model.interfaces[0].law.normal.k == 1e14 and cfg.model.damping.ratio == 1e-3
    assert cfg.model.interfaces[0].gap.kind == "height"
