"""Interface laws from plain tables (TOML ``[interface.law]``, results.json)."""
from __future__ import annotations

from ...errors import InputError
from .interface import InterfaceLaw
from .exponential import ExponentialPressure
from .hard import Hard
from .linear import LinearPressure
from .rough import RoughSurface
from .tabular import TabularPressure
from .tangential import ElasticStick, RigidStick

#: normal law name -> (class, {table key: constructor argument})
NORMAL_KEYS = {
    "hard": (Hard, {}),
    "linear": (LinearPressure, {"normal_stiffness": "k"}),
    "exponential": (ExponentialPressure, {"clearance": "c0", "pressure_at_zero": "p0",
                                          "form": "form"}),
    "tabular": (TabularPressure, {"table": "table"}),
    "rough": (RoughSurface, {"sigma": "sigma", "radius": "radius", "density": "density",
                             "E": "E", "nu": "nu", "yield_strength": "yield_strength",
                             "hardening": "hardening", "n_sigma": "n_sigma"}),
}
#: Keys a table may leave out (the law's default applies).
OPTIONAL_KEYS = {"yield_strength", "hardening", "n_sigma", "form"}
#: tangential law name -> (class, {table key: constructor argument})
TANGENTIAL_KEYS = {
    "rigid": (RigidStick, {}),
    "elastic": (ElasticStick, {"tangential_stiffness": "k"}),
}


def register_normal_law(name, cls, keys):
    """Make a normal law available to tables under ``name`` (``keys``: table key ->
    constructor argument)."""
    NORMAL_KEYS[name] = (cls, dict(keys))


def law_from_table(table, where="interface law") -> InterfaceLaw:
    """The :class:`InterfaceLaw` of a table ``{"normal": name, <its keys>,
    "tangential": name, <its keys>}``; every key checked, unknown ones refused with the
    list of accepted ones."""
    if not isinstance(table, dict):
        raise InputError(f"{where}: expected a table (e.g. normal = \"linear\", "
                         f"normal_stiffness = 1e14), got {table!r}")
    normal_name = table.get("normal", "hard")
    tangential_name = table.get("tangential")
    if normal_name not in NORMAL_KEYS:
        raise InputError(f"{where}: normal = {normal_name!r} is not a normal law; choose "
                         f"one of {sorted(NORMAL_KEYS)}")
    if tangential_name is not None and tangential_name not in TANGENTIAL_KEYS:
        raise InputError(f"{where}: tangential = {tangential_name!r} is not a tangential "
                         f"law; choose one of {sorted(TANGENTIAL_KEYS)}")
    n_cls, n_keys = NORMAL_KEYS[normal_name]
    t_cls, t_keys = TANGENTIAL_KEYS[tangential_name] if tangential_name else (None, {})
    allowed = {"normal", "tangential", *n_keys, *t_keys}
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise InputError(f"{where}: unknown key(s) {unknown} for normal = {normal_name!r}"
                         f"{'' if tangential_name is None else f', tangential = {tangential_name!r}'}"
                         f"; accepted: {sorted(allowed)}")
    normal = n_cls(**_arguments(table, n_keys, where, f"normal = {normal_name!r}"))
    tangential = None if t_cls is None else \
        t_cls(**_arguments(table, t_keys, where, f"tangential = {tangential_name!r}"))
    return InterfaceLaw(normal, tangential)


def _arguments(table, keys, where, what):
    missing = [k for k in keys if k not in table and k not in OPTIONAL_KEYS]
    if missing:
        raise InputError(f"{where}: {what} needs {missing}")
    return {arg: table[key] for key, arg in keys.items()
            if key in table and table[key] is not None}
