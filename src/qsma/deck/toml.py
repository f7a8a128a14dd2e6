"""A deck's configuration as the text of a TOML file (``qsma init deck.inp``): every
setting spelled out, what the deck holds that the run does not use as comments."""
from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
import re

import numpy as np

from ..analysis.options import RunOptions
from ..version import __version__
from .records import Deck

def deck_toml(deck: Deck, folder=None) -> str:
    """The configuration of ``deck`` as the text of a TOML file in ``folder`` (default:
    the deck's): every setting spelled out (the run options at their defaults included),
    each value's origin in the deck as a comment, and the deck's notes at the top. Read
    back with :func:`qsma.config.load_config` it gives ``deck.config``."""
    folder = Path(folder) if folder is not None else deck.source.parent
    mesh = Path(os.path.relpath(deck.source.resolve(), folder.resolve())).as_posix()
    config = dict(deck.config, bodies=[dict(b, mesh=mesh) for b in deck.config["bodies"]])
    c = deck.comments
    out = [f"# qsma configuration of {deck.source.name}, written by `qsma init` (qsma "
           f"{__version__}).", "# Every setting is spelled out; docs/config.md describes "
           "each key. Run it with", "#   qsma run <this file> --out <result folder>"]
    refused = [n for n in deck.notes if n.refuses]
    kept = [n for n in deck.notes if not n.refuses]
    if refused:
        out += ["#", "# NOT MODELLED: `qsma run` of the deck refuses these; this file runs "
                "WITHOUT them,", "# which answers another problem than the deck's unless "
                "you change the model:"]
        out += [f"#   {n}" for n in refused]
    if kept:
        out += ["#", "# Not used from the deck (the run does not need them):"]
        out += [f"#   {n}" for n in kept]
    out += ["", f"name = {_toml(config['name'])}"]
    if "units" in config:
        out.append(_line(f"units = {_toml(config['units'])}", c.get(("units",))))
    for k, b in enumerate(config["bodies"]):
        out += ["", _line("[[bodies]]", c.get(("bodies", k, "name")))]
        for key, value in b.items():
            if isinstance(value, list) and value and isinstance(value[0], dict):
                out.append(f"{key} = [")
                out += [_line(f"  {_toml(v)},", c.get(("bodies", k, key, j)))
                        for j, v in enumerate(value)]
                out.append("]")
            else:
                out.append(_line(f"{key} = {_toml(value)}", c.get(("bodies", k, key))))
    if "interface" in config:
        out += ["", _line("[interface]", c.get(("interface",)))]
        out += [f"{key} = {_toml(v)}" for key, v in config["interface"].items()]
    else:
        for j, t in enumerate(config["interfaces"]):
            out += ["", _line("[[interfaces]]", c.get(("interfaces", j)))]
            out += [f"{key} = {_toml(v)}" for key, v in t.items()]
    for j, t in enumerate(config.get("bolts", [])):
        out += ["", _line("[[bolts]]", c.get(("bolts", j)))]
        out += [f"{key} = {_toml(v)}" for key, v in t.items()]
    out += ["", _line("[tip]", c.get(("tip",)))]
    out += [f"{key} = {_toml(v)}" for key, v in config["tip"].items()]
    out += ["", "[analysis]"] + _analysis_lines(config["analysis"])
    out += ["", _line("[levels]", c.get(("levels",)))]
    out += [f"{key} = {_toml(v)}" for key, v in config["levels"].items()]
    return "\n".join(out) + "\n"


def _line(text, comment):
    return f"{text:<30s} # {comment}" if comment else text


def _toml(value) -> str:
    """A TOML value: strings, booleans, numbers (``repr``: read back exactly), lists and
    inline tables of them."""
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"no TOML form for {value!r}")


def _analysis_lines(analysis) -> list:
    """Every run option: the deck's, else its default (commented out where the default
    is 'not set'), each with the first sentence of its documentation."""
    helps = _option_help()
    lines = []
    for f in dataclasses.fields(RunOptions):
        if f.name == "levels":
            continue
        value = analysis.get(f.name, f.default)
        text = f"{f.name} = {_toml(value)}" if value is not None else f"# {f.name} ="
        lines.append(_line(text, helps.get(f.name, "")))
    return lines


def _option_help() -> dict:
    """``{option: first sentence}`` from the Parameters section of RunOptions' docstring."""
    doc = RunOptions.__doc__.split("Parameters")[1].split("\n")
    out, names = {}, []
    for line in doc:
        m = re.fullmatch(r"    ([\w, ]+) : .*", line)
        if m:
            names = [n.strip() for n in m.group(1).split(",")]
            for n in names:
                out[n] = ""
            continue
        if names and line.startswith("        "):
            for n in names:
                if not out[n].endswith("."):
                    out[n] = (out[n] + " " + line.strip()).strip()
                    out[n] = out[n].split(". ")[0] + ("." if ". " in out[n] else "")
    return {k: re.sub(r":\w+:`~?([^`]+)`", lambda m: m.group(1).split(".")[-1],
                      v).replace("``", "") for k, v in out.items()}
