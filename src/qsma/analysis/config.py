"""TOML configuration of a QSMA run: model from mesh files, loads, interface, levels,
solver options. Every key is checked: unknown, missing and mistyped keys are named
with the allowed ones."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from ..contact.laws import law_from_table
from ..errors import InputError, MeshFileError
from ..model import (Body, Bolt, Clamp, Interface, LinearDamping, Material, Model, NodalForce,
                     PointMass, Pressure, Probe, Spring, read_gap_field)
from ..model.touching import with_touching_sets
from ..fe.formulation import with_element
from ..units import unit_system
from .levels import Levels, spec_levels
from .options import RunOptions

_NUM = (int, float)
# section -> {key: (types, required)}
SCHEMA = {
    "": {"name": (str, False), "units": (str, False), "bodies": (list, True),
         "interface": (dict, False), "interfaces": (list, False), "bolts": (list, False),
         "damping": (dict, False),
         "tip": (dict, True), "analysis": (dict, False), "levels": (dict, False)},
    "bodies": {"name": (str, True), "mesh": (str, True), "cells": (str, False),
               "part": (int, False), "element": (str, False), "E": (_NUM, True),
               "nu": (_NUM, True), "rho": (_NUM, True), "clamps": (list, False),
               "pressures": (list, False), "springs": (list, False),
               "masses": (list, False), "forces": (list, False)},
    "clamps": {"set": (str, True), "components": (list, False), "dofs": (list, False),
               "displacement": (list, False)},
    "springs": {"set": (str, True), "stiffness": (list, True)},
    "masses": {"set": (str, True), "mass": (_NUM, True)},
    "bolts": {"name": (str, True), "body_a": (str, True), "set_a": (str, True),
              "body_b": (str, True), "set_b": (str, True), "pretension": (_NUM, True),
              "stiffness": (_NUM, True)},
    "pressures": {"set": (str, True), "p": (_NUM, True), "load": (str, False),
                  "face": (int, False)},
    "forces": {"set": (str, True), "force": (list, True), "load": (str, False)},
    "interface": {"body1": (str, True), "set1": (str, False), "body2": (str, True),
                  "set2": (str, False), "touching": (bool, False), "mu": (_NUM, True), "tol": (_NUM, False),
                  "coupling": (str, False), "slave": (str, False), "law": (dict, False),
                  "gap": (dict, False), "adjust": (_NUM + (str,), False)},
    "interfaces": {"body1": (str, True), "set1": (str, False), "body2": (str, True),
                   "set2": (str, False), "touching": (bool, False), "mu": (_NUM, True), "tol": (_NUM, False),
                   "coupling": (str, False), "slave": (str, False), "law": (dict, False),
                   "gap": (dict, False), "adjust": (_NUM + (str,), False)},
    "gap": {"file": (str, True), "scale": (_NUM, False), "coordinate_scale": (_NUM, False)},
    "damping": {"ratio": (_NUM, False), "rayleigh": (list, False)},
    "tip": {"sets": (list, False), "points": (list, False), "direction": (list, True)},
    "levels": {"kind": (str, True), "spacing": (str, True), "start": (_NUM, False),
               "stop": (_NUM, False), "n": (int, False), "values": (list, False)},
}


#: How each table is written in a file, for the messages.
_TABLE_NAMES = {"": "the top level", "bodies": "[[bodies]]", "clamps": "a body's clamps",
                "springs": "a body's springs", "pressures": "a body's pressures",
                "masses": "a body's masses", "bolts": "[[bolts]]",
                "forces": "a body's forces",
                "interface": "[interface]", "interfaces": "[[interfaces]]", "tip": "[tip]",
                "levels": "[levels]", "analysis": "[analysis]"}


def _key_hint(key, section) -> str:
    """`` (...)``: where an unknown key belongs, or the nearest allowed key."""
    import difflib
    tables = dict(SCHEMA, analysis=dict(RunOptions.table_keys(), modes=list))
    owners = [_TABLE_NAMES[t] for t, keys in tables.items() if key in keys and t != section]
    if owners:
        return f" (it belongs in {' or '.join(owners)})"
    close = difflib.get_close_matches(key, SCHEMA[section], n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


@dataclass(frozen=True)
class RunConfig:
    """A model and the options of :func:`qsma.run` (the ``[analysis]`` table is
    :class:`qsma.analysis.options.RunOptions`, its keys are that class's fields, and ``modes``:
    several modes, one backbone each, as ``qsma run --modes``; ``None``: one run of
    ``options.mode``)."""

    model: Model
    options: RunOptions
    modes: tuple | None = None


def _check(table, section, where):
    if not isinstance(table, dict):
        raise InputError(f"{where}: expected a table, got {type(table).__name__}")
    schema = SCHEMA[section]
    for key in table:
        if key not in schema:
            raise InputError(f"{where}: unknown key {key!r}{_key_hint(key, section)}; "
                             f"allowed keys: {sorted(schema)}")
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
    from ..mesh.io.common import read_regular
    path = Path(path)
    text = decode_toml(read_regular(path, "a TOML configuration"), str(path))
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
    return decode_utf8(raw, where, "TOML files")


def decode_utf8(raw: bytes, where: str, kind: str) -> str:
    """The text of a file that must be UTF-8 (a byte-order mark accepted);
    :class:`InputError` naming the encoding problem, the line and the fix otherwise.
    ``kind`` names the files in the message (e.g. "TOML files")."""
    if raw.startswith(_UTF32_BOMS) or raw.startswith(_UTF16_BOMS) or b"\x00" in raw[:200]:
        raise InputError(f"{where}: the file is encoded as UTF-16 or UTF-32; {kind} "
                         f"must be UTF-8. Save it as UTF-8 (e.g. iconv -f UTF-16 -t UTF-8)")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise InputError(f"{where}, line {line}: byte 0x{raw[exc.start]:02x} is not UTF-8 "
                         f"(Latin-1 or another 8-bit encoding?); {kind} must be UTF-8. "
                         f"Save the file as UTF-8 (e.g. iconv -f LATIN1 -t UTF-8)") from None


def _interface(t, where, base, with_mu=True) -> Interface:
    law = law_from_table(t["law"], f"{where}.law") if "law" in t else None
    gap = None
    if "gap" in t:
        g = _check(t["gap"], "gap", f"{where}.gap")
        gap = read_gap_field(base / g["file"], scale=g.get("scale", 1.0),
                             coordinate_scale=g.get("coordinate_scale", 1.0))
    return Interface(t["body1"], t["set1"], t["body2"], t["set2"], t.get("tol"),
                     coupling=t.get("coupling", "auto"), slave=t.get("slave"),
                     mu=t["mu"] if with_mu else None, law=law, gap=gap,
                     adjust=t.get("adjust"))


def _with_touching(tables, bodies, wheres) -> list:
    """Interface tables with ``set1``/``set2`` filled where ``touching = true`` (the
    facet sets found where the two bodies touch, added to ``bodies`` in place); each
    other table must name both sets."""
    out, pending = [], []
    for t, where in zip(tables, wheres):
        named = [k for k in ("set1", "set2") if k in t]
        if t.get("touching", False):
            if named:
                raise InputError(f"{where}: touching = true finds the contact faces; "
                                 f"leave out {' and '.join(named)}, or touching")
            pending.append((len(out), where))
        elif len(named) < 2:
            missing = sorted({"set1", "set2"} - set(named))
            raise InputError(f"{where}: missing required key {missing[0]!r}: name the "
                             f"facet sets in contact (set1, set2), or let qsma find the "
                             f"faces where the bodies touch with touching = true")
        out.append(dict(t))
    for k, where in pending:
        try:
            ((s1, s2),) = with_touching_sets(bodies, [(out[k]["body1"], out[k]["body2"])])
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None
        out[k].update(set1=s1, set2=s2)
        del out[k]["touching"]
    return out


def _damping(table, where):
    """The ``[damping]`` table: ``ratio = 0.00087`` or ``rayleigh = [alpha, beta]``."""
    if table is None:
        return None
    _check(table, "damping", where)
    if ("ratio" in table) == ("rayleigh" in table):
        raise InputError(f"{where}: give exactly one of ratio (a modal damping ratio, e.g. "
                         f"0.00087) or rayleigh = [alpha, beta]")
    if "ratio" in table:
        return LinearDamping(ratio=table["ratio"])
    ab = table["rayleigh"]
    if len(ab) != 2:
        raise InputError(f"{where}: rayleigh must be [alpha (1/s), beta (s)], got {ab!r}")
    return LinearDamping(alpha=ab[0], beta=ab[1])


def _body_mesh(path, cells, files, part=None):
    """The mesh of a body: the whole file, its cell set ``cells`` or its connected part
    number ``part`` (from 1; one file read once for all the bodies taken from it)."""
    from ..mesh.io import read_mesh
    if part is not None:
        if cells is not None:
            raise InputError("give either cells (a cell set) or part (a connected part "
                             "of the mesh), not both")
        meshes = files.setdefault(("parts", str(path)),
                                  _assembly(path, files).component_meshes())
        if not 1 <= part <= len(meshes):
            raise InputError(f"part = {part}: {path} has {len(meshes)} connected part(s) "
                             f"(cells joined through shared nodes), numbered from 1")
        return meshes[part - 1]
    if cells is None:
        try:
            return read_mesh(path)
        except MeshFileError as exc:
            sets = _cell_sets(path, files)
            if len(sets) < 2:
                raise
            raise MeshFileError(f"{path} holds {len(sets)} cell sets {sets} and was read as "
                                f"one body without 'cells': if it holds several bodies, "
                                f"name this body's cell set in its [[bodies]] table, e.g. "
                                f"cells = {sets[0]!r}. Reading it whole gave: {exc}") from exc
    return _assembly(path, files).body_mesh(cells)


def _assembly(path, files):
    """The :class:`qsma.mesh.io.Assembly` of ``path``, read once per configuration."""
    from ..mesh.io import read_assembly
    key = str(path)
    if key not in files:
        files[key] = read_assembly(path)
    return files[key]


def _cell_sets(path, files) -> list:
    """The cell sets of a mesh file (empty if it cannot be read as an assembly)."""
    try:
        return _assembly(path, files).cell_sets
    except InputError:
        return []


def _check_whole_files(tables, base, files, where):
    """Two bodies reading one file whole (no ``cells``) would be the same mesh twice:
    point to ``cells``."""
    whole = {}
    for k, b in enumerate(tables):
        if "cells" not in b and "part" not in b:
            whole.setdefault(str(base / b["mesh"]), []).append(b["name"])
    for path, names in whole.items():
        if len(names) > 1:
            sets = _cell_sets(Path(path), files)
            example = f"e.g. cells = {sets[0]!r}; cell sets of the file: {sets}" if sets \
                else "the file names no cell set: give each body its own mesh file"
            raise InputError(f"{where}: bodies {names} all read {path} whole (no 'cells'), "
                             f"so each would be the whole mesh; take each body out of the "
                             f"file by its cell set with 'cells' in its [[bodies]] table "
                             f"({example})")


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
        ``[analysis]`` (the fields of :class:`qsma.analysis.options.RunOptions`) and ``[levels]``.
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
    if not data["bodies"]:
        raise InputError(f"{where}: bodies is empty; describe each body as a [[bodies]] "
                         f"table (name, mesh, E, nu, rho, clamps, pressures)")
    bodies = []
    files = {}
    for k, b in enumerate(data["bodies"]):
        _check(b, "bodies", f"{where}: bodies[{k}]")
        if "\x00" in b["mesh"] or not b["mesh"].strip():
            raise InputError(f"{where}: bodies[{k}]: mesh path {b['mesh']!r} is empty or "
                             f"contains a NUL character; give the mesh file name")
    _check_whole_files(data["bodies"], base, files, where)
    for k, b in enumerate(data["bodies"]):
        w = f"{where}: bodies[{k}]"
        tables = {key: [_check(t, key, f"{w}.{key}") for t in b.get(key, [])]
                  for key in ("clamps", "masses", "pressures", "springs", "forces")}
        clamps = tuple(_clamp(c, f"{w}.clamps") for c in tables["clamps"])
        try:
            mat = Material(b["E"], b["nu"], b["rho"])
            masses = tuple(PointMass(t["set"], t["mass"]) for t in tables["masses"])
            springs = tuple(Spring(t["set"], tuple(t["stiffness"])) for t in tables["springs"])
            forces = tuple(NodalForce(t["set"], tuple(t["force"]), t.get("load", "preload"))
                           for t in tables["forces"])
            mesh = _body_mesh(base / b["mesh"], b.get("cells"), files, b.get("part"))
            if "element" in b:
                mesh = with_element(mesh, b["element"])
            mesh, pressures = _pressures(mesh, tables["pressures"])
            bodies.append(Body(b["name"], mesh, mat, clamps, pressures, springs, masses,
                               forces))
        except InputError as exc:
            raise InputError(f"{w} ({b['name']!r}): {exc}") from exc
    tip = _check(data["tip"], "tip", f"{where}: tip")
    bodies, probe = _probe(tip, bodies, f"{where}: tip")
    bodies = list(bodies)
    name = data.get("name", "model")
    damping = _damping(data.get("damping"), f"{where}: damping")
    if ("interface" in data) == ("interfaces" in data):
        raise InputError(f"{where}: give the contact interface as one [interface] table "
                         f"(two bodies) or as a list of [[interfaces]] tables (any number "
                         f"of bodies), exactly one of the two")
    bolts = tuple(Bolt(**_check(t, "bolts", f"{where}: bolts[{k}]"))
                  for k, t in enumerate(data.get("bolts", [])))
    if "interface" in data:
        itf = _check(data["interface"], "interface", f"{where}: interface")
        (itf,) = _with_touching([itf], bodies, [f"{where}: interface"])
        model = Model(bodies=tuple(bodies),
                      interface=_interface(itf, f"{where}: interface", base, with_mu=False),
                      tip=probe, mu=itf["mu"], name=name, bolts=bolts, units=units,
                      damping=damping)
    else:
        if not data["interfaces"]:
            raise InputError(f"{where}: interfaces is empty; list the touching facet sets "
                             f"as [[interfaces]] tables")
        tables = [_check(t, "interfaces", f"{where}: interfaces[{k}]")
                  for k, t in enumerate(data["interfaces"])]
        tables = _with_touching(tables, bodies, [f"{where}: interfaces[{k}]"
                                                 for k in range(len(tables))])
        itfs = tuple(_interface(t, f"{where}: interfaces[{k}]", base)
                     for k, t in enumerate(tables))
        model = Model(bodies=tuple(bodies), interfaces=itfs, tip=probe, mu=itfs[0].mu,
                      name=name, bolts=bolts, units=units, damping=damping)
    analysis = dict(data.get("analysis", {})) if isinstance(data.get("analysis"), dict) \
        else data.get("analysis", {})
    modes = _modes(analysis, f"{where}: analysis")
    levels = (spec_levels(model.units) if data.get("levels") is None
              else parse_levels(data["levels"], f"{where}: levels"))
    options = RunOptions.from_table(analysis, f"{where}: analysis", levels=levels)
    return RunConfig(model, options, modes)


def config_modes(path) -> tuple | None:
    """The ``modes`` of a configuration file's ``[analysis]`` table (None if it gives
    none), read without its meshes: the command line chooses one run or several before
    it loads the model."""
    from ..mesh.io.common import read_regular
    path = Path(path)
    try:
        data = tomllib.loads(decode_toml(read_regular(path, "a TOML configuration"),
                                         str(path)))
    except (InputError, tomllib.TOMLDecodeError):
        return None                    # load_config names the problem
    analysis = data.get("analysis")
    return _modes(dict(analysis), f"{path}: analysis") if isinstance(analysis, dict) else None


def _pressures(mesh, tables):
    """``(mesh, pressures)``: a table with ``face = k`` loads face S<k> of the cells of
    cell set ``set`` (an Abaqus ``*DLOAD, set, P<k>``), a facet set ``<set>:S<k>`` added
    to the mesh for it."""
    from ..mesh.io.abaqus import element_face_facets
    extra, pressures = {}, []
    for t in tables:
        name = t["set"]
        if "face" in t:
            name = f"{t['set']}:S{t['face']}"
            extra[name] = element_face_facets(mesh, t["set"], t["face"])
        pressures.append(Pressure(name, t["p"], t.get("load", "preload")))
    return (mesh.with_sets(facet_sets=extra) if extra else mesh), tuple(pressures)


def _probe(tip, bodies, where):
    """``(bodies, Probe)`` from the ``[tip]`` table: ``sets`` of ``[body, set]`` pairs, or
    ``points`` of ``[body, [x, y(, z)]]``, each the body's node nearest to the point (a
    node set ``_tip`` is added to those bodies)."""
    from dataclasses import replace
    if ("sets" in tip) == ("points" in tip):
        raise InputError(f"{where}: give either sets = [[body, set], ...] or points = "
                         f"[[body, [x, y, z]], ...], exactly one of the two")
    if "sets" in tip:
        sets = tip["sets"]
        if not all(isinstance(s, list) and len(s) == 2 and all(isinstance(x, str) for x in s)
                   for s in sets):
            raise InputError(f"{where}: tip.sets must be a list of [body, set] pairs, got "
                             f"{sets!r}")
        return bodies, Probe(tuple(tuple(s) for s in sets), tuple(tip["direction"]))
    by_name = {b.name: b for b in bodies}
    nodes = {}
    for item in tip["points"]:
        if not (isinstance(item, list) and len(item) == 2 and item[0] in by_name
                and isinstance(item[1], list)
                and len(item[1]) == by_name[item[0]].dim
                and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                        for v in item[1])):
            raise InputError(f"{where}: tip.points must be [body, [x, y(, z)]] pairs naming "
                             f"bodies {sorted(by_name)}, got {item!r}")
        nodes.setdefault(item[0], []).append(_nearest_node(by_name[item[0]], item[1], where))
    bodies = [replace(b, mesh=b.mesh.with_sets(node_sets={"_tip": np.unique(nodes[b.name])}))
              if b.name in nodes else b for b in bodies]
    return bodies, Probe(tuple((name, "_tip") for name in nodes), tuple(tip["direction"]))


#: A probe point farther than this fraction of its body's size from every node is a
#: mistake (a typo, another unit), not a choice of node.
POINT_TOLERANCE = 0.01


def _nearest_node(body, point, where) -> int:
    x = body.mesh.points
    d = np.linalg.norm(x - np.asarray(point, float), axis=1)
    k = int(np.argmin(d))
    size = float(np.linalg.norm(x.max(axis=0) - x.min(axis=0)))
    if d[k] > POINT_TOLERANCE * size:
        raise InputError(f"{where}: point {point} is {d[k]:.4g} from the nearest node of body "
                         f"{body.name!r} (at {x[k].tolist()}), more than "
                         f"{POINT_TOLERANCE:g} of the body's size {size:.4g}: give a point "
                         f"on the body")
    return k


def _clamp(table, where) -> Clamp:
    """A clamp from its table: ``components`` counts from 0 (0 = x), ``dofs`` from 1 as
    Abaqus and CalculiX do (1 = x); neither: every direction."""
    if "components" in table and "dofs" in table:
        raise InputError(f"{where}: give either components (0 = x, 1 = y, 2 = z) or dofs "
                         f"(1 = x, 2 = y, 3 = z, as in Abaqus), not both")
    if "dofs" in table:
        dofs = table["dofs"]
        if not dofs or not all(isinstance(d, int) and not isinstance(d, bool) and 1 <= d <= 3
                               for d in dofs):
            raise InputError(f"{where}: dofs must be a list of degrees of freedom 1, 2 or 3 "
                             f"(1 = x, 2 = y, 3 = z, counted from 1 as in Abaqus and "
                             f"CalculiX), got {dofs!r}")
        return Clamp(table["set"], tuple(d - 1 for d in dofs), _displacement(table, where))
    return Clamp(table["set"], tuple(table["components"]) if "components" in table else None,
                 _displacement(table, where))


def _displacement(table, where):
    """A clamp's prescribed ``displacement`` (one number per component held), or None."""
    if "displacement" not in table:
        return None
    v = table["displacement"]
    if not all(isinstance(x, _NUM) and not isinstance(x, bool) for x in v):
        raise InputError(f"{where}: displacement must be a list of numbers, one per "
                         f"component held (in the model's length unit), got {v!r}")
    return tuple(float(x) for x in v)


def _modes(analysis, where):
    """``modes`` of the ``[analysis]`` table, taken out of it (distinct integers >= 0),
    or None."""
    if not isinstance(analysis, dict) or "modes" not in analysis:
        return None
    modes = analysis.pop("modes")
    if not (isinstance(modes, list) and modes and len(set(modes)) == len(modes)
            and all(isinstance(k, int) and not isinstance(k, bool) and k >= 0
                    for k in modes)):
        raise InputError(f"{where}: modes must be a list of distinct mode indices >= 0 "
                         f"(0 = lowest), e.g. modes = [0, 1, 2]; got {modes!r}")
    if "mode" in analysis:
        raise InputError(f"{where}: give either mode = K (one mode) or modes = [K1, K2, ...] "
                         f"(one backbone each), not both")
    return tuple(modes)


def parse_levels(table, where="levels") -> Levels:
    if table is None:
        return spec_levels()
    _check(table, "levels", where)
    kind, spacing = table["kind"], table["spacing"]
    if spacing == "list":
        if "values" not in table:
            raise InputError(f"{where}: spacing 'list' needs key 'values'")
        given = [key for key in ("start", "stop", "n") if key in table]
        if given:
            raise InputError(f"{where}: spacing 'list' takes its levels from 'values'; "
                             f"{', '.join(repr(k) for k in given)} given too would be "
                             f"ignored: remove them, or use spacing 'log' or 'linear' "
                             f"without 'values'")
        values = table["values"]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            raise InputError(f"{where}: values must be a list of numbers, got {values!r}")
        return Levels(kind, tuple(values))
    if spacing not in ("log", "linear"):
        raise InputError(f"{where}: spacing must be 'log', 'linear' or 'list', got {spacing!r}")
    for key in ("start", "stop", "n"):
        if key not in table:
            raise InputError(f"{where}: spacing {spacing!r} needs key {key!r}")
    if "values" in table:
        raise InputError(f"{where}: spacing {spacing!r} makes its levels from start, stop "
                         f"and n, but 'values' is given too; remove it, or use spacing "
                         f"'list'")
    make = Levels.log if spacing == "log" else Levels.linear
    return make(kind, table["start"], table["stop"], table["n"])
