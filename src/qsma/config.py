"""TOML configuration of a QSMA run: model from mesh files, loads, interface, levels,
solver options. Every key is checked: unknown, missing and mistyped keys are named
with the allowed ones."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from .errors import InputError
from .levels import Levels, spec_levels
from .options import RunOptions
from .units import unit_system
from .model import Body, Clamp, Interface, Material, Model, Pressure, Probe, Spring

_NUM = (int, float)
# section -> {key: (types, required)}
SCHEMA = {
    "": {"name": (str, False), "units": (str, False), "bodies": (list, True),
         "interface": (dict, False),
         "interfaces": (list, False),
         "tip": (dict, True), "analysis": (dict, False), "levels": (dict, False)},
    "bodies": {"name": (str, True), "mesh": (str, True), "cells": (str, False),
               "E": (_NUM, True),
               "nu": (_NUM, True), "rho": (_NUM, True), "clamps": (list, False),
               "pressures": (list, False), "springs": (list, False)},
    "clamps": {"set": (str, True), "components": (list, False)},
    "springs": {"set": (str, True), "stiffness": (list, True)},
    "pressures": {"set": (str, True), "p": (_NUM, True), "load": (str, False)},
    "interface": {"body1": (str, True), "set1": (str, True), "body2": (str, True),
                  "set2": (str, True), "mu": (_NUM, True), "tol": (_NUM, False),
                  "coupling": (str, False), "slave": (str, False)},
    "interfaces": {"body1": (str, True), "set1": (str, True), "body2": (str, True),
                   "set2": (str, True), "mu": (_NUM, True), "tol": (_NUM, False),
                   "coupling": (str, False), "slave": (str, False)},
    "tip": {"sets": (list, True), "direction": (list, True)},
    "levels": {"kind": (str, True), "spacing": (str, True), "start": (_NUM, False),
               "stop": (_NUM, False), "n": (int, False), "values": (list, False)},
}


@dataclass(frozen=True)
class RunConfig:
    """A model and the options of :func:`qsma.run` (the ``[analysis]`` table is
    :class:`qsma.options.RunOptions`, its keys are that class's fields)."""

    model: Model
    options: RunOptions


def _check(table, section, where):
    if not isinstance(table, dict):
        raise InputError(f"{where}: expected a table, got {type(table).__name__}")
    schema = SCHEMA[section]
    for key in table:
        if key not in schema:
            raise InputError(f"{where}: unknown key {key!r}; allowed keys: {sorted(schema)}")
    for key, (types, required) in schema.items():
        if key not in table:
            if required:
                raise InputError(f"{where}: missing required key {key!r}")
            continue
        v = table[key]
        ok = isinstance(v, types) and not (isinstance(v, bool) and types in (_NUM, int))
        if not ok:
            tname = "number" if types is _NUM else getattr(types, "__name__", str(types))
            raise InputError(f"{where}: key {key!r} must be a {tname}, got {v!r}")
    return table


def load_config(path) -> RunConfig:
    """Read a TOML run configuration (mesh paths relative to the file's folder).

    The file must be UTF-8 (the TOML standard); a UTF-8 byte-order mark is accepted.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read configuration {str(path)!r}: {exc.strerror}") from exc
    text = decode_toml(raw, str(path))
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from exc
    return parse_config(data, base=path.parent, where=str(path))


_UTF16_BOMS = (b"\xff\xfe", b"\xfe\xff")
_UTF32_BOMS = (b"\xff\xfe\x00\x00", b"\x00\x00\xfe\xff")


def decode_toml(raw: bytes, where: str) -> str:
    """The text of a TOML file; :class:`InputError` naming the encoding problem, the line
    and the fix when the bytes are not UTF-8."""
    if raw.startswith(_UTF32_BOMS) or raw.startswith(_UTF16_BOMS) or b"\x00" in raw[:200]:
        raise InputError(f"{where}: the file is encoded as UTF-16 or UTF-32; TOML files "
                         f"must be UTF-8. Save it as UTF-8 (e.g. iconv -f UTF-16 -t UTF-8)")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise InputError(f"{where}, line {line}: byte 0x{raw[exc.start]:02x} is not UTF-8 "
                         f"(Latin-1 or another 8-bit encoding?); TOML files must be UTF-8. "
                         f"Save the file as UTF-8 (e.g. iconv -f LATIN1 -t UTF-8)") from None


def _interface(t, with_mu=True) -> Interface:
    return Interface(t["body1"], t["set1"], t["body2"], t["set2"], t.get("tol"),
                     coupling=t.get("coupling", "auto"), slave=t.get("slave"),
                     mu=t["mu"] if with_mu else None)


def _body_mesh(path, cells, files):
    """The mesh of a body: the whole file, or its cell set ``cells`` (one file read once
    for all the bodies taken from it)."""
    from .model.io import read_mesh, read_assembly
    if cells is None:
        return read_mesh(path)
    key = str(path)
    if key not in files:
        files[key] = read_assembly(path)
    return files[key].body_mesh(cells)


def parse_config(data, base=Path("."), where="config") -> RunConfig:
    """A :class:`RunConfig` from a parsed TOML table.

    Parameters
    ----------
    data : dict
        The parsed file: ``units`` (the unit system every number is in,
        :data:`qsma.units.UNIT_SYSTEMS`, default ``"SI"``), ``[[bodies]]`` (mesh file,
        material, clamps, pressures,
        grounded springs ``springs = [{set = ..., stiffness = [kx, ky(, kz)]}]``, or
        ``cells`` to take a body out of a file holding several), one ``[interface]`` or
        a list ``[[interfaces]]`` (each with its own ``mu`` if wanted), ``[tip]``,
        ``[analysis]`` (the fields of :class:`qsma.options.RunOptions`) and ``[levels]``.
    base : pathlib.Path
        Folder that relative mesh paths start from (the configuration file's).
    where : str
        Name of the source in error messages.

    Returns
    -------
    RunConfig
        The model and the run options.

    Raises
    ------
    InputError
        An unknown key, a missing or ill-typed value, a mesh that cannot be read; the
        message names the table and key.

    Examples
    --------
    >>> import tomllib
    >>> from qsma.examples import example_file
    >>> path = example_file("sandwich-2d.toml")
    >>> cfg = parse_config(tomllib.loads(path.read_text()), base=path.parent)
    """
    _check(data, "", where)
    units = data.get("units", "SI")
    try:
        unit_system(units)
    except InputError as exc:
        raise InputError(f"{where}: units: {exc}") from None
    bodies = []
    files = {}
    for k, b in enumerate(data["bodies"]):
        w = f"{where}: bodies[{k}]"
        _check(b, "bodies", w)
        clamps = tuple(Clamp(c["set"], tuple(c["components"]) if "components" in c else None)
                       for c in (_check(c, "clamps", f"{w}.clamps") for c in
                                 b.get("clamps", [])))
        pressures = tuple(Pressure(p["set"], p["p"], p.get("load", "preload"))
                          for p in (_check(p, "pressures", f"{w}.pressures") for p in
                                    b.get("pressures", [])))
        spring_tables = [_check(t, "springs", f"{w}.springs") for t in b.get("springs", [])]
        if "\x00" in b["mesh"] or not b["mesh"].strip():
            raise InputError(f"{w}: mesh path {b['mesh']!r} is empty or contains a NUL "
                             f"character; give the mesh file name")
        try:
            mat = Material(b["E"], b["nu"], b["rho"])
            springs = tuple(Spring(t["set"], tuple(t["stiffness"])) for t in spring_tables)
            mesh = _body_mesh(base / b["mesh"], b.get("cells"), files)
            bodies.append(Body(b["name"], mesh, mat, clamps, pressures, springs))
        except InputError as exc:
            raise InputError(f"{w} ({b['name']!r}): {exc}") from exc
    tip = _check(data["tip"], "tip", f"{where}: tip")
    sets = tip["sets"]
    if not all(isinstance(s, list) and len(s) == 2 and all(isinstance(x, str) for x in s)
               for s in sets):
        raise InputError(f"{where}: tip.sets must be a list of [body, set] pairs, got {sets!r}")
    probe = Probe(tuple(tuple(s) for s in sets), tuple(tip["direction"]))
    name = data.get("name", "model")
    if ("interface" in data) == ("interfaces" in data):
        raise InputError(f"{where}: give the contact interface as one [interface] table "
                         f"(two bodies) or as a list of [[interfaces]] tables (any number "
                         f"of bodies), exactly one of the two")
    if "interface" in data:
        itf = _check(data["interface"], "interface", f"{where}: interface")
        model = Model(bodies=tuple(bodies), interface=_interface(itf, with_mu=False),
                      tip=probe, mu=itf["mu"], name=name, units=units)
    else:
        if not data["interfaces"]:
            raise InputError(f"{where}: interfaces is empty; list the touching facet sets "
                             f"as [[interfaces]] tables")
        itfs = tuple(_interface(_check(t, "interfaces", f"{where}: interfaces[{k}]"))
                     for k, t in enumerate(data["interfaces"]))
        model = Model(bodies=tuple(bodies), interfaces=itfs, tip=probe, mu=itfs[0].mu,
                      name=name, units=units)
    levels = (spec_levels(model.units) if data.get("levels") is None
              else parse_levels(data["levels"], f"{where}: levels"))
    options = RunOptions.from_table(data.get("analysis", {}), f"{where}: analysis",
                                    levels=levels)
    return RunConfig(model, options)


def parse_levels(table, where="levels") -> Levels:
    if table is None:
        return spec_levels()
    _check(table, "levels", where)
    kind, spacing = table["kind"], table["spacing"]
    if spacing == "list":
        if "values" not in table:
            raise InputError(f"{where}: spacing 'list' needs key 'values'")
        values = table["values"]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            raise InputError(f"{where}: values must be a list of numbers, got {values!r}")
        return Levels(kind, tuple(values))
    if spacing not in ("log", "linear"):
        raise InputError(f"{where}: spacing must be 'log', 'linear' or 'list', got {spacing!r}")
    for key in ("start", "stop", "n"):
        if key not in table:
            raise InputError(f"{where}: spacing {spacing!r} needs key {key!r}")
    make = Levels.log if spacing == "log" else Levels.linear
    return make(kind, table["start"], table["stop"], table["n"])
