"""What a study varies and the cases it makes: the parameters a sweep accepts, their
values from a spec (:func:`parse_values`), the cartesian grid (:func:`grid`) bounded
by the memory its records take, and what a case changes of the model and of the run
options (:func:`model_with_materials`, :func:`case_inputs`): shared by the sweeps
(:mod:`.sweep`) and the fits (:mod:`.fit`)."""
from __future__ import annotations

from dataclasses import dataclass, replace
import itertools

import numpy as np

from ..errors import InputError
from ..analysis.levels import Levels
from ..analysis.options import EXECUTION_FIELDS, RunOptions

#: Parameters that change the model rather than the run options. ``E``, ``nu``, ``rho``
#: may name a body (``E:bottom``); without a body they apply to every body.
MODEL_PARAMETERS = ("mu", "preload")
MATERIAL_PARAMETERS = ("E", "nu", "rho")
#: Memory a case holds in the calling process until the study ends, per load level: its
#: rows of the study table (33 columns of Python objects: 43 kB per case of 51 levels,
#: measured with tracemalloc over 200 cases of sandwich-2d) and their CSV text, with
#: a margin for the report; plus a fixed part for the case, its outcome and its entry
#: in study.json.
CASE_BYTES, LEVEL_BYTES = 4096, 2048
#: Share of the free memory (:func:`qsma._infra.resources.free_memory`) a study's cases may
#: take; where the system does not say, :data:`MAX_CASES_UNKNOWN_MEMORY` cases.
CASES_MEMORY_SHARE, MAX_CASES_UNKNOWN_MEMORY = 0.5, 100_000
#: Run options a sweep does not vary: the execution options change no result
#: (:data:`qsma.analysis.options.EXECUTION_FIELDS`; a sweep's workers compute their
#: loops and ramps themselves: a daemonic process may not fork), the BLAS thread count
#: is the machine's business, and the condensation backend is fixed when the shared
#: preparation is made.
NOT_SWEPT = ("blas_threads", "schur_backend") + EXECUTION_FIELDS


@dataclass(frozen=True)
class Case:
    """One case of a study: its index in the grid and its parameter values."""

    index: int
    params: tuple          # ((name, value), ...) in the order of ``vary``

    @property
    def name(self) -> str:
        return f"case-{self.index:04d}"

    def as_dict(self) -> dict:
        return dict(self.params)

    def json_params(self) -> dict:
        """Parameters as JSON values (levels as ``{"kind", "values"}``)."""
        return {k: _json_value(v) for k, v in self.params}


def parameter_kind(name: str) -> str:
    """``"model"``, ``"material"`` or ``"option"``; unknown names raise with the valid ones."""
    base = name.split(":", 1)[0]
    if name in MODEL_PARAMETERS:
        return "model"
    if base in MATERIAL_PARAMETERS:
        return "material"
    options = sorted(set(RunOptions.__dataclass_fields__) - set(NOT_SWEPT))
    if name in options:
        return "option"
    raise InputError(f"unknown sweep parameter {name!r}; valid: mu, preload, "
                     f"E|nu|rho[:BODY], or a run option {options}")


def parse_values(name: str, spec) -> list:
    """Values of a parameter from ``START:STOP:N`` (N evenly spaced, ends included) or
    ``V1,V2,...``; a list or tuple is taken as is (``levels``: :class:`qsma.Levels`)."""
    parameter_kind(name)
    if not isinstance(spec, str):
        values = list(spec) if isinstance(spec, (list, tuple, np.ndarray)) else [spec]
    elif name == "levels":
        raise InputError(f"levels values must be qsma.Levels objects, got the text "
                         f"{spec!r} (the command line parses level specs)")
    else:
        parts = spec.split(":")
        try:
            if len(parts) == 3:
                start, stop, n = float(parts[0]), float(parts[1]), int(parts[2])
                if n < 1:
                    raise ValueError
            elif len(parts) == 1:
                values = [_scalar(v) for v in spec.split(",") if v.strip()]
            else:
                raise ValueError
        except ValueError:
            raise InputError(f"--vary {name}={spec!r}: expected START:STOP:N (e.g. "
                             f"0.2:0.8:10) or a list V1,V2,... (e.g. 0.3,0.5,0.7)") from None
        if len(parts) == 3:
            if n == 1 and start != stop:
                raise InputError(f"--vary {name}={spec}: one value from {start:g} to "
                                 f"{stop:g}: it would be {start:g} and {stop:g} ignored; "
                                 f"give the value alone ({name}={start:g})")
            check_case_count(n, f"--vary {name}={spec}")
            values = np.linspace(start, stop, n).tolist()
    if not values:
        raise InputError(f"--vary {name}: no values given")
    return [_typed(name, v) for v in values]


def grid(vary: dict, n_levels: int | None = None) -> list:
    """The cases of the cartesian product of ``vary`` (name -> values or spec), the last
    parameter varying fastest; refused before it is made when the study could not hold
    them (:func:`check_case_count`, with cases of ``n_levels`` load levels)."""
    if not vary:
        raise InputError("a sweep needs at least one parameter to vary, e.g. "
                         "vary={'mu': [0.3, 0.5]} or --vary mu=0.3,0.5")
    names = list(vary)
    values = [parse_values(n, vary[n]) for n in names]
    check_case_count(int(np.prod([len(v) for v in values], dtype=object)),
                     " x ".join(f"{len(v)} {n}" for n, v in zip(names, values)), n_levels)
    return [Case(i, tuple(zip(names, combo)))
            for i, combo in enumerate(itertools.product(*values))]


def max_cases(n_levels: int = 1) -> int:
    """Most cases of ``n_levels`` load levels a study may have: those whose rows and
    records (:data:`CASE_BYTES`, :data:`LEVEL_BYTES`) fit in :data:`CASES_MEMORY_SHARE`
    of the free memory."""
    from .._infra.resources import free_memory
    free = free_memory()
    if free is None:
        return MAX_CASES_UNKNOWN_MEMORY
    return max(1, int(CASES_MEMORY_SHARE * free // (CASE_BYTES + n_levels * LEVEL_BYTES)))


def check_case_count(n: int, what: str, n_levels: int | None = None):
    """Refuse ``n`` cases (from ``what``, for messages) beyond :func:`max_cases` of
    ``n_levels`` levels (None: not known yet, counted as one), before anything of them
    is made (the 10^10 values of such a grid alone take 74.5 GiB as doubles)."""
    most = max_cases(n_levels or 1)
    if n > most:
        of = (f"of {n_levels} load level(s), about "
              f"{(CASE_BYTES + n_levels * LEVEL_BYTES) / 1024:.0f} kB each until the study "
              f"ends" if n_levels else "even of one load level each")
        raise InputError(f"{what}: {n} cases, but this machine's free memory holds the "
                         f"records of at most {most} cases ({of}): ask for fewer values, "
                         f"or split the study into several folders")


def _scalar(text):
    t = text.strip()
    if t.lower() in ("true", "false"):
        return t.lower() == "true"
    for cast in (int, float):
        try:
            return cast(t)
        except ValueError:
            pass
    return t


def _typed(name, v):
    if name == "levels":
        if not isinstance(v, Levels):
            raise InputError(f"levels values must be qsma.Levels, got {v!r}")
        return v
    kind = parameter_kind(name)
    if kind in ("model", "material"):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) \
                or not np.isfinite(v):
            raise InputError(f"sweep parameter {name!r} needs numbers, got {v!r}")
        return float(v)
    if isinstance(v, (float, np.floating)) and float(v).is_integer() and \
            RunOptions.__dataclass_fields__[name].type in ("int", "int | None"):
        return int(v)
    if isinstance(v, np.generic):
        return v.item()
    return v


def _json_value(v):
    if isinstance(v, Levels):
        return {"kind": v.kind, "values": list(v.values)}
    return v


def table_value(v):
    if isinstance(v, Levels):
        return f"{v.kind}:{len(v.values)}:{v.values[0]:.6g}..{v.values[-1]:.6g}"
    return v


# ------------------------------------------------------------ what a case changes

def material_key(case, n_bodies, names):
    """Per body, ``(E, nu, rho)`` overrides of the case (None = the model's)."""
    out = []
    for k in range(n_bodies):
        over = {}
        for name, v in case.params:
            base, _, body = name.partition(":")
            if base in MATERIAL_PARAMETERS and (not body or body == names[k]):
                over[base] = v
        out.append(tuple(sorted(over.items())))
    return tuple(out)


def check_bodies(cases, model):
    """Refuse before any case a body the model lacks and a friction coefficient the
    model's interfaces would not see (their own mu)."""
    from ..analysis import STUDY_MU_FIX
    names = [b.name for b in model.bodies]
    for name, _ in cases[0].params:
        base, _, body = name.partition(":")
        if base in MATERIAL_PARAMETERS and body and body not in names:
            raise InputError(f"parameter {name!r}: no body {body!r}; bodies: {names}")
    for mu in sorted({dict(c.params)["mu"] for c in cases if "mu" in dict(c.params)}):
        model.check_mu_reaches(mu, STUDY_MU_FIX, what=f"mu = {mu:g} of the study")


def model_with_materials(model, key):
    from ..model import Material
    bodies = []
    for b, over in zip(model.bodies, key):
        if over:
            m = b.material
            vals = {**dict(E=m.E, nu=m.nu, rho=m.rho), **dict(over)}
            b = replace(b, material=Material(vals["E"], vals["nu"], vals["rho"]))
        bodies.append(b)
    return replace(model, bodies=tuple(bodies))


def case_inputs(prepared, params: dict, options: RunOptions):
    """``(prepared, options)`` of a case: its friction coefficient and preload scale
    applied to its group's preparation (nothing recomputed), its run options set. The
    case computes its loops itself (no ``loop_scheduler``): the study's workers are the
    parallel part, and a case waiting on a worker for loops that wait for a worker
    could hold them all."""
    p = prepared
    if "mu" in params:
        p = p.with_mu(params["mu"])
    if "preload" in params:
        p = p.with_preload_scale(params["preload"])
    opts = replace(options.replace(**{k: v for k, v in params.items()
                                      if parameter_kind(k) == "option"}),
                   loop_scheduler=None)
    return p, opts
