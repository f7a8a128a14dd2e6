r"""Parameter studies: a grid of QSMA cases sharing the work they have in common.

A study is the cartesian product of the values given per parameter (:func:`grid`).
Work is shared between cases as far as the method allows (docs/theory.md, "What a
sweep reuses"):

- friction coefficient ``mu`` and preload scale ``preload``: assembly and static
  condensation are done once (:func:`qsma.analysis.prepare`); a preload scale
  :math:`s` multiplies the condensed 'preload' pattern (the condensed loads are linear
  in the pressures); the tied modes are recomputed only when the set of pairs closed
  by the preload changes (cached by that mask);
- ``mode``, ``levels`` and other run options: the preload solve and the tied modes
  are reused as well;
- material constants ``E``, ``nu``, ``rho`` (of all bodies, or of one as
  ``E:bottom``): the changed body is re-assembled, both are condensed again.

Cases run as tasks: by default on processes forked from this one, which inherit
the preparations (nothing pickled, nothing condensed or factorised again); on Dask
(:mod:`distributed`): a :class:`distributed.LocalCluster` (``scheduler="dask"``, or
where this process may not fork), any scheduler by address; or serially in this
process (``scheduler="serial"``). Each case writes a folder as ``qsma run`` does
(:func:`qsma.output.files.write_all`) and then a done-marker; a study started again in the
same folder skips the cases whose marker exists. A failing case is recorded with its
message and the others go on. The study table (:data:`TABLE_NAME`) has a row per case
and level, read back from the case folders, so a resumed study and a fresh one give
the same table.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import csv
import io
import itertools
import json
import logging
from pathlib import Path
import re
import threading
import time
import warnings

import numpy as np

from ..errors import InputError, QSMAError, SerialSweepWarning
from ..levels import Levels
from ..options import RunOptions
from ..output.folders import MANIFEST, StudyFolder

log = logging.getLogger("qsma")

#: Parameters that change the model rather than the run options. ``E``, ``nu``, ``rho``
#: may name a body (``E:bottom``); without a body they apply to every body.
MODEL_PARAMETERS = ("mu", "preload")
MATERIAL_PARAMETERS = ("E", "nu", "rho")
#: File names inside the study folder (docs/studies.md describes each).
STUDY_NAME, TABLE_NAME, PARQUET_NAME = "study.json", "study.csv", "study.parquet"
#: Written beside a case folder (``case-0003.done.json``) once the case is finished:
#: its presence marks the case as done. Outside the folder, so that the folder is
#: exactly what ``qsma run`` writes (a result folder holds one run and nothing else).
DONE_SUFFIX = ".done.json"
#: Workers of the default local cluster: one process per core of the 2-core machines
#: this package is developed on (fewer where fewer cores are usable); ``workers=`` or
#: ``--workers`` changes it, up to the usable cores.
DEFAULT_WORKERS = 2
CASE_FILES = ("plots", "vtu", "rom", "report")
#: Memory a case holds in the calling process until the study ends, per load level: its
#: rows of the study table (33 columns of Python objects: 43 kB per case of 51 levels,
#: measured with tracemalloc over 200 cases of sandwich-2d) and their CSV text, with
#: a margin for the report; plus a fixed part for the case, its outcome and its entry
#: in study.json.
CASE_BYTES, LEVEL_BYTES = 4096, 2048
#: Share of the free memory (:func:`qsma._infra.resources.free_memory`) a study's cases may
#: take; where the system does not say, :data:`MAX_CASES_UNKNOWN_MEMORY` cases.
CASES_MEMORY_SHARE, MAX_CASES_UNKNOWN_MEMORY = 0.5, 100_000
#: Run options a sweep does not vary: the BLAS thread count, the loop workers, the
#: loop scheduler and the parallel ramps do not change results (a sweep's workers
#: compute their loops and ramps themselves: a daemonic process may not fork), the
#: condensation backend is fixed when the shared preparation is made.
NOT_SWEPT = ("blas_threads", "schur_backend", "loop_workers", "loop_scheduler",
             "parallel_ramps")
#: Run options left out of a study's fingerprint: they change no result, so a study
#: resumes whatever they are.
NOT_FINGERPRINTED = ("loop_workers", "loop_scheduler", "parallel_ramps")


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


@dataclass(frozen=True)
class CaseOutcome:
    """What became of a case: ``status`` is ``"ok"``, ``"unsuccessful"`` (computed but
    ``success`` is False: see ``message``) or ``"failed"`` (nothing computed)."""

    index: int
    params: dict
    status: str
    message: str
    seconds: float
    folder: str
    skipped: bool = False


@dataclass(frozen=True, eq=False)
class SweepResult:
    """A study: the outcome per case, the table (column name -> list) and the files."""

    success: bool
    message: str
    cases: tuple
    table: dict
    paths: dict
    parameters: tuple
    n_failed: int
    n_skipped: int
    timings_s: dict = field(default_factory=dict)


# ---------------------------------------------------------------------------- the grid

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
    is made (a grid of 10^10 cases asked for 74.5 GiB)."""
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


def _table_value(v):
    if isinstance(v, Levels):
        return f"{v.kind}:{len(v.values)}:{v.values[0]:.6g}..{v.values[-1]:.6g}"
    return v


# ------------------------------------------------------------------- preparing the cases

def _material_key(case, n_bodies, names):
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


def _check_bodies(cases, model):
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


def _model_with_materials(model, key):
    from ..model import Material
    bodies = []
    for b, over in zip(model.bodies, key):
        if over:
            m = b.material
            vals = {**dict(E=m.E, nu=m.nu, rho=m.rho), **dict(over)}
            b = replace(b, material=Material(vals["E"], vals["nu"], vals["rho"]))
        bodies.append(b)
    return replace(model, bodies=tuple(bodies))


def _prepare_groups(model, options, cases):
    """One :class:`qsma.analysis.Prepared` per distinct set of material constants;
    bodies whose constants are those of another group reuse its assembly."""
    from ..analysis import prepare
    names = [b.name for b in model.bodies]
    groups, by_body = {}, {}
    for case in cases:
        key = _material_key(case, len(model.bodies), names)
        if key in groups:
            continue
        m = _model_with_materials(model, key)
        keep = [by_body.get((k, over)) for k, over in enumerate(key)]
        prep = prepare(m, options, assembled=keep)
        for k, over in enumerate(key):
            by_body.setdefault((k, over), prep.assembled[k])
        groups[key] = prep
    return groups


# ------------------------------------------------------------------------ running a case

def run_case(prepared, case: Case, options: RunOptions, folder, files=()) -> CaseOutcome:
    """Run one case from its group's preparation, write its folder and, last, its
    done-marker. Errors are caught and recorded: a case never stops the study."""
    from ..analysis import run_prepared
    from ..output.files import atomic_write, write_all
    t0, c0 = time.perf_counter(), time.process_time()
    params = case.as_dict()
    status, message = "ok", "all levels converged"
    try:
        res = run_prepared(*case_inputs(prepared, params, options))
        write_all(res, folder, plots="plots" in files, vtu="vtu" in files,
                  report="report" in files)
        if "rom" in files and res.n_levels:
            from .rom import export_rom
            export_rom(res, Path(folder).with_name(Path(folder).name + ".rom.json"))
        if not res.success:
            status, message = "unsuccessful", res.message
    except QSMAError as exc:
        status, message = "failed", f"{type(exc).__name__}: {exc}"
    except Exception as exc:        # recorded, the study goes on; the message names it
        status, message = "failed", f"internal error {type(exc).__name__}: {exc}"
    res = None
    _free_cycles(prepared.reduced.K.shape[0])
    seconds = time.perf_counter() - t0
    marker = dict(index=case.index, params=case.json_params(), status=status,
                  message=message, seconds=seconds, cpu_seconds=time.process_time() - c0)
    atomic_write(done_path(folder), json.dumps(marker, indent=1) + "\n")
    return CaseOutcome(case.index, params, status, message, seconds, str(folder))


#: Contact DOFs from which a case ends with a full garbage collection
#: (:func:`_free_cycles`): the dense interface matrices then weigh 8 MB or more each.
FREE_CYCLES_FROM = 1000


def _free_cycles(n_contact_dofs):
    """One full collection of the cyclic garbage collector after a case of
    ``n_contact_dofs`` >= :data:`FREE_CYCLES_FROM` contact DOFs.

    A run leaves some of its contact problems in reference cycles (a problem caches
    its contact-zone elimination, which refers back to the problem): about 57 MB per
    sandwich-3d refine 1 run (docs/performance.md, "Memory of repeated runs in one
    process"). Only a full collection frees them, which a process running case
    after case may not do for many cases. It costs about 40 ms: negligible against
    a 3D case, 4 % of a sandwich-2d case, whose cycles hold little (skipped there)."""
    if n_contact_dofs >= FREE_CYCLES_FROM:
        import gc
        gc.collect()


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


def done_path(folder) -> Path:
    """The done-marker of the case folder ``folder``: ``<folder>.done.json``."""
    folder = Path(folder)
    return folder.with_name(folder.name + DONE_SUFFIX)


def _done(case, folder):
    """The outcome recorded in ``folder`` for ``case``, or None if it is to be run: no
    marker, a failed case (a failure may be passing, e.g. a full disk: retried), or a
    marker whose result folder is gone."""
    path = done_path(folder)
    if not path.exists():
        return None
    marker = json.loads(path.read_text())
    if marker.get("status") == "failed" or not (Path(folder) / "results.json").exists():
        return None
    if marker.get("params") != _roundtrip(case.json_params()):
        raise InputError(f"{path} records parameters {marker.get('params')} but case "
                         f"{case.index} of this study is {case.json_params()}: the folder "
                         f"holds another study; choose another output folder")
    return CaseOutcome(case.index, case.as_dict(), marker["status"], marker["message"],
                       marker["seconds"], str(folder), skipped=True)


def _roundtrip(x):
    return json.loads(json.dumps(x))


# --------------------------------------------------------------------------- the study

def sweep(model_or_config, vary: dict, options: RunOptions | None = None, *, out,
          scheduler=None, workers: int | None = None, files=(), plots=True,
          progress=None, amplitude=None) -> SweepResult:
    """Run a parameter study: every case of the grid ``vary``, sharing the work the
    cases have in common (module docstring), on Dask or serially.

    Parameters
    ----------
    model_or_config : :class:`qsma.model.Model` or :class:`qsma.config.RunConfig`
    vary : dict
        Parameter name -> values (list) or spec (``"0.2:0.8:10"``, ``"0.3,0.5"``); names:
        ``mu``, ``preload`` (scale of every 'preload' pressure), ``E``/``nu``/``rho``
        (``E:BODY`` for one body), ``mode``, ``levels`` or another run option.
    options : RunOptions, optional
        Options of every case (a config's options when ``None``).
    out : path
        Study folder: :data:`STUDY_NAME`, :data:`TABLE_NAME`, figures, one folder per case.
    scheduler : None, "serial", "dask", str or distributed.Client
        ``None``: ``workers`` processes forked from this one (where it may not fork:
        a local Dask cluster, or without Dask the cases in this process with a
        :class:`qsma.errors.SerialSweepWarning`); ``"serial"`` (or ``workers=0``): in
        this process, in order; ``"dask"``: a local Dask cluster of ``workers``
        processes; an address (``tcp://host:8786``) or a client: that scheduler (the
        workers must see ``out``).
    workers : int
        Processes of the local pool or cluster, at most the usable cores (default
        :data:`DEFAULT_WORKERS`, or the cores if fewer).
    files : iterable of {"plots", "vtu", "rom", "report"}
        Per-case files besides results.json and results.csv (rom: :mod:`qsma.study.rom`,
        written beside the case folder as ``case-NNNN.rom.json``; report: the case's
        report.html, :mod:`qsma.output.report`).
    plots : bool
        Study figures (frequency and damping versus amplitude per parameter); the
        study's report.html is written in any case.
    progress : callable, optional
        ``progress(done, total)`` after each case (skipped ones included).
    amplitude : str, optional
        The amplitude measure of the study figures (:data:`qsma.output.plots.AMPLITUDES`,
        default the peak tip deflection, as a run's figures).

    Returns
    -------
    SweepResult
    """
    from ..config import RunConfig
    t0 = time.perf_counter()
    if isinstance(model_or_config, RunConfig):
        model = model_or_config.model
        options = model_or_config.options if options is None else options
    else:
        model = model_or_config
    options = options or RunOptions()
    files = tuple(files)
    for f in files:
        if f not in CASE_FILES:
            raise InputError(f"unknown per-case file kind {f!r}; valid: {CASE_FILES}")
    if workers is None:
        from .._infra.threads import usable_cores
        workers = min(DEFAULT_WORKERS, usable_cores())
    if amplitude is not None:
        from ..output.plots import check_amplitude
        check_amplitude(amplitude)
    if not (isinstance(workers, int) and workers >= 0):
        raise InputError(f"workers must be an integer >= 0, got {workers!r}")
    _check_workers(workers, scheduler)
    cases = grid(vary, n_levels=_most_levels(vary, options))
    _check_bodies(cases, model)
    _check_scheduler(scheduler)
    with StudyFolder(out, allowed=_in_study) as folder:   # locked before computing
        return _study(folder, model, vary, options, cases, scheduler, workers, files,
                      plots, progress, t0, amplitude)


def _study(folder, model, vary, options, cases, scheduler, workers, files, plots, progress,
           t0, amplitude=None) -> SweepResult:
    """:func:`sweep` in its entered :class:`qsma.output.folders.StudyFolder` (manifest written
    when every case is done)."""
    from ..output.files import atomic_write
    out = folder.path
    study = dict(model=model.name, fingerprint=_fingerprint(model, options),
                 parameters=list(vary), n_cases=len(cases),
                 cases=[c.json_params() for c in cases])
    _check_study(out / STUDY_NAME, study)
    folder.changing()
    atomic_write(out / STUDY_NAME, json.dumps(study, indent=1) + "\n")

    outcomes, todo = {}, []
    for c in cases:
        done = _done(c, out / c.name)
        if done is None:
            todo.append(c)
        else:
            outcomes[c.index] = done
    n_total = len(cases)
    if progress is not None:
        progress(len(outcomes), n_total)
    t_prep = time.perf_counter()
    groups = _prepare_groups(model, options, todo) if todo else {}
    t_prep = time.perf_counter() - t_prep
    names = [b.name for b in model.bodies]
    key_of = lambda c: _material_key(c, len(model.bodies), names)
    run = _runner(scheduler, workers, len(todo))
    for outcome in (run(groups, key_of, todo, options, out, files, scheduler, workers)
                    if todo else ()):
        outcomes[outcome.index] = outcome
        if progress is not None:
            progress(len(outcomes), n_total)
    ordered = tuple(outcomes[c.index] for c in cases)
    table = study_table(cases, ordered, out)
    paths = write_table(table, out, units=model.units, dim=model.dim)
    figures = {}
    if plots:
        from .plots import plot_study
        figures = plot_study(table, list(vary), out, units=model.units, dim=model.dim,
                             amplitude=amplitude)
        paths.update(figures)
    from ..output.report import REPORT_NAME, write_study_report
    paths["report"] = write_study_report(list(vary), ordered, table,
                                         {k[len("plot_"):]: v for k, v in figures.items()},
                                         out / REPORT_NAME)
    paths["manifest"] = out / MANIFEST
    folder.commit()
    failed = [o for o in ordered if o.status == "failed"]
    bad = [o for o in ordered if o.status != "ok"]
    message = "all cases succeeded" if not bad else (
        f"{len(failed)} case(s) failed and {len(bad) - len(failed)} did not succeed: "
        + "; ".join(f"case {o.index} {o.params}: {o.message}" for o in bad[:5])
        + (" ..." if len(bad) > 5 else ""))
    return SweepResult(not bad, message, ordered, table, paths, tuple(vary), len(failed),
                       sum(o.skipped for o in ordered),
                       dict(prepare=t_prep, total=time.perf_counter() - t0))


#: Names a study folder holds besides its manifest (``case-0003``, its done-marker and
#: rom.json, the table, figures and report); anything else is refused as foreign.
_STUDY_ENTRY = re.compile(r"case-\d{4,}(\.done\.json|\.rom\.json)?|study\.(json|csv|parquet)"
                          r"|report\.html|sweep_.+\.png")


def _in_study(name: str) -> bool:
    return _STUDY_ENTRY.fullmatch(name) is not None


def _check_study(path, study):
    """Refuse to resume into a folder of another study: other cases, or the same cases
    of another model or other run options (their results would be mixed)."""
    if not path.exists():
        return
    old = json.loads(path.read_text())
    if old.get("cases") != _roundtrip(study["cases"]):
        raise InputError(f"{path.parent} holds another study ({old.get('n_cases')} cases "
                         f"over {old.get('parameters')}); to resume, give the same "
                         f"parameters, else choose another output folder")
    if old.get("fingerprint") != study["fingerprint"]:
        raise InputError(f"{path.parent} holds a study of the same cases but another model "
                         f"or other run options (levels, method, mode, ...): its results "
                         f"would be mixed with this one's; choose another output folder or "
                         f"rerun with the options it was made with")


def _fingerprint(model, options) -> str:
    """SHA-256 of what a case's results depend on besides its own parameters: the model
    as a whole (:func:`qsma.model.fingerprint.fingerprint`: meshes with the contents of
    every set, materials, clamps, loads, springs, interfaces, probe, mu, bolts) and
    every run option that changes a result (levels included)."""
    import hashlib
    from ..model.fingerprint import fingerprint
    h = hashlib.sha256()
    h.update(fingerprint(model).encode())
    h.update(repr(sorted((k, _fingerprinted(model, k, v))
                         for k, v in options.as_dict().items()
                         if k not in NOT_FINGERPRINTED)).encode())
    h.update(repr(options.levels).encode())
    return h.hexdigest()


def _fingerprinted(model, name, value):
    """The value of option ``name`` as the fingerprint holds it: ``method="auto"`` of a
    2D model as the method it always runs (``basket``), so the two spellings resume each
    other's studies. In 3D the choice depends on the number of interface pairs, known
    only after the pairing, so ``"auto"`` stays ``"auto"``."""
    if name == "method" and value == "auto" and model.dim == 2:
        return "basket"
    return value


def distributed_available() -> bool:
    """Whether Dask's ``distributed`` (the extra ``sweep``) can be imported."""
    import importlib.util
    try:
        return importlib.util.find_spec("distributed") is not None
    except (ImportError, ValueError):       # a module set to None in sys.modules
        return False


def _runner(scheduler, workers, n_todo):
    """How the cases run (module docstring): in this process (``"serial"``, or no
    scheduler and ``workers == 0``); on ``workers`` processes forked from this one (no
    scheduler: :func:`_run_forked`), or where this process may not fork on a local
    Dask cluster, or without Dask in this process with a
    :class:`qsma.errors.SerialSweepWarning`; on Dask (``"dask"``: a local cluster, an
    address or a client: :func:`_run_dask`)."""
    from .._infra.forked import fork_refusal
    if scheduler == "serial" or (scheduler is None and workers == 0) or n_todo == 0:
        return _run_serial
    if scheduler is not None:
        return _run_dask
    why_not = fork_refusal()
    if why_not is None:
        return _run_forked
    if distributed_available():
        log.info("cases on a local Dask cluster, not on forked processes: %s", why_not)
        return _run_dask
    warnings.warn(f"the {n_todo} case(s) run one after the other in this process: it "
                  f"may not fork workers ({why_not}) and the 'distributed' package is not "
                  f"installed (for a local cluster of {workers} workers: pip install "
                  f"'qsma[sweep]')", SerialSweepWarning, stacklevel=3)
    return _run_serial


#: The job of the forked case workers: set before the fork, inherited by the workers
#: (with the preparations it refers to), never pickled.
_CASE_JOB = None


def _call_case(i):
    """``_CASE_JOB(i)`` and the warnings it raised, for this process to raise again."""
    from .._infra.forked import recorded_warnings
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        out = _CASE_JOB(i)
    return i, out, recorded_warnings(seen)


#: Run options of a case on a forked worker: the worker is one of ``workers`` processes
#: that share the cores, so it forks no loop workers nor a second ramp of its own (the
#: results are the same bits either way, docs/performance.md).
FORKED_CASE_OPTIONS = dict(loop_workers=1, parallel_ramps=False)


def _run_forked(groups, key_of, todo, options, out, files, scheduler, workers):
    """Cases as tasks of ``workers`` processes forked from this one. The preparations
    reach the workers by the fork itself, with everything this process computed
    (condensed model, factorisations, cached preload solves and tied modes): nothing
    is pickled but a case's index and its outcome, nothing is condensed or factorised
    again, and the pool starts in milliseconds where a Dask cluster takes seconds. A
    worker that dies (killed, out of memory) breaks the pool: the cases not finished
    are given to a new pool once; if that breaks too, they are recorded as failed."""
    global _CASE_JOB
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool
    from .._infra.forked import default_signals, quiet_fork, raise_again
    opts = options.replace(**FORKED_CASE_OPTIONS)
    _CASE_JOB = lambda i: run_case(groups[key_of(todo[i])], todo[i], opts,
                                   out / todo[i].name, files)
    pending = list(range(len(todo)))
    try:
        for attempt in range(2):
            with quiet_fork():
                pool = ProcessPoolExecutor(min(workers, len(pending)),
                                           mp_context=multiprocessing.get_context("fork"),
                                           initializer=default_signals)
            broken = None
            try:
                futures = [pool.submit(_call_case, i) for i in pending]
                for fut in as_completed(futures):
                    try:
                        i, outcome, raised = fut.result()
                    except BrokenProcessPool as exc:
                        broken = exc
                        continue
                    raise_again(raised)
                    pending.remove(i)
                    yield outcome
            finally:
                pool.shutdown(wait=True, cancel_futures=True)
            if broken is None or not pending:
                return
            log.warning("a case worker died (%s): %d case(s) given to a new pool",
                        broken, len(pending))
        for i in pending:
            c = todo[i]
            yield CaseOutcome(c.index, c.as_dict(), "failed",
                              f"worker error: the worker process died twice ({broken})",
                              float("nan"), str(out / c.name))
    finally:
        _CASE_JOB = None


def _most_levels(vary, options) -> int:
    """The most load levels a case of the study has (its levels, or the default 51)."""
    from ..levels import spec_levels
    given = [v for v in vary.get("levels", ()) if isinstance(v, Levels)] \
        if not isinstance(vary.get("levels", ()), str) else []
    levels = given + [options.levels or spec_levels()]
    return max(len(lv.values) for lv in levels)


def _check_workers(workers, scheduler):
    """Refuse a local cluster of more worker processes than the cores this process may
    use (:func:`qsma._infra.threads.usable_cores`): each case is a CPU-bound process, so the
    extra ones only compete for the cores (6 workers on a 2-core machine started 7
    processes). A cluster of more machines is reached by a scheduler address."""
    from .._infra.threads import usable_cores
    if scheduler is not None:
        return
    cores = usable_cores()
    if workers > cores:
        raise InputError(f"--workers {workers}: this machine lets qsma use {cores} core(s); "
                         f"more local worker processes than cores only compete for them. "
                         f"Give --workers {cores} or fewer, or --scheduler ADDRESS to run "
                         f"on a Dask cluster of more machines")


def _check_scheduler(scheduler):
    """Refuse, before any work, a scheduler address that is not one (the connection
    itself is tried when the cases are sent)."""
    if not isinstance(scheduler, str) or scheduler == "serial":
        return
    try:
        from distributed.comm import parse_address
        from distributed.comm.addressing import parse_host_port
    except ImportError:
        return                          # said when the cases are sent (_run_dask)
    try:
        protocol, location = parse_address(scheduler)
        if protocol in ("tcp", "tls", "ws", "wss"):
            parse_host_port(location)
    except (ValueError, TypeError) as exc:
        raise InputError(f"--scheduler {scheduler!r} is not a Dask scheduler address "
                         f"({exc}); give one such as tcp://host:8786, or drop --scheduler "
                         f"to run on a local cluster") from None


def _run_serial(groups, key_of, todo, options, out, files, scheduler, workers):
    for c in todo:
        yield run_case(groups[key_of(c)], c, options, out / c.name, files)


def _run_dask(groups, key_of, todo, options, out, files, scheduler, workers):
    """Cases as Dask tasks; each group's preparation is scattered once to every
    worker with its condensed model (:meth:`qsma.analysis.Prepared.__reduce__`: no
    condensation on the workers, one ``K_EE`` factorisation per body and worker when
    first needed)."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError as exc:      # dask is the optional extra 'sweep'
        raise InputError(f"parallel sweeps need the 'distributed' package ({exc}): "
                         f"pip install 'qsma[sweep]', or run the cases one after the "
                         f"other with scheduler='serial' (--workers 0)") from None
    cluster = None
    if scheduler in (None, "dask"):
        try:
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                   processes=True, dashboard_address=None,
                                   silence_logs=logging.ERROR)
        except Exception as exc:    # e.g. no process spawning in a sandbox
            raise QSMAError(f"a local Dask cluster of {workers} processes could not "
                            f"start ({type(exc).__name__}: {exc}); run the cases serially "
                            f"(--workers 0, scheduler='serial') or give --scheduler "
                            f"ADDRESS") from exc
        client = Client(cluster)
    elif isinstance(scheduler, str):
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}; "
                             f"start one (dask scheduler) or drop --scheduler") from None
    else:
        client = scheduler
    try:
        shared = {k: client.scatter(p, broadcast=True, hash=False)
                  for k, p in groups.items()}
        futures = {client.submit(run_case, shared[key_of(c)], c, options, out / c.name,
                                 files, pure=False): c for c in todo}
        for fut in as_completed(futures):
            c = futures[fut]
            try:
                yield fut.result()
            except Exception as exc:    # the worker died: recorded, the others go on
                yield CaseOutcome(c.index, c.as_dict(), "failed",
                                  f"worker error {type(exc).__name__}: {exc}", float("nan"),
                                  str(out / c.name))
    finally:
        if client is not scheduler:
            client.close()
        if cluster is not None:
            cluster.close()


# --------------------------------------------------------------------------- the table

def table_columns(parameters) -> tuple:
    """Columns of the study table: case, parameters, status, message, then those of a
    run's results.csv (:func:`qsma.output.files.csv_columns`)."""
    from ..output.files import csv_columns
    return ("case",) + tuple(parameters) + ("status", "message") + csv_columns()


def study_table(cases, outcomes, out) -> dict:
    """Column name -> list, a row per case and level, read from the case folders
    (a case without levels has one row with empty level values)."""
    from ..output.files import csv_columns
    params = [n for n, _ in cases[0].params]
    cols = {c: [] for c in table_columns(params)}
    level_cols = csv_columns()
    for case, o in zip(cases, outcomes):
        path = out / case.name / "results.json"
        levels = json.loads(path.read_text())["levels"] if o.status != "failed" and \
            path.exists() else {}
        n = len(levels.get("alpha", []))
        for k in range(max(n, 1)):
            cols["case"].append(case.index)
            for name, v in case.params:
                cols[name].append(_table_value(v))
            cols["status"].append(o.status)
            cols["message"].append(o.message)
            for c in level_cols:
                if n == 0:
                    cols[c].append(None)
                elif c == "level":
                    cols[c].append(k)
                else:
                    cols[c].append(levels[c][k])
    return cols


def write_table(table, out, units="SI", dim=3) -> dict:
    """Write the study table as CSV (always) and Parquet (when pyarrow is installed);
    the CSV header names the units of the level columns in the model's system
    (``tip [m]``, as results.csv)."""
    from ..output.files import atomic_path, atomic_write, _csv_cell
    from ..units import column_label, level_units
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    names = list(table)
    unit = level_units(units, dim)
    w.writerow([column_label(c, unit.get(c)) for c in names])
    n = len(table[names[0]]) if names else 0
    for i in range(n):
        w.writerow([_csv_cell(table[c][i]) for c in names])
    paths = {"table": Path(out) / TABLE_NAME}
    atomic_write(paths["table"], buf.getvalue())
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return paths
    cols = {c: [";".join(v) if isinstance(v, list) else v for v in vals]
            for c, vals in table.items()}
    paths["parquet"] = Path(out) / PARQUET_NAME
    with atomic_path(paths["parquet"]) as tmp:
        pq.write_table(pa.table(cols), tmp)
    return paths


def read_table(path) -> dict:
    """The study CSV as column name (its unit left out: ``tip [m]`` -> ``tip``) -> list
    of strings (empty cells as '')."""
    from ..output.files import column_name
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return {column_name(name): [r[i] for r in rows[1:]] for i, name in enumerate(rows[0])}


__all__ = ["sweep", "grid", "parse_values", "Case", "CaseOutcome", "SweepResult",
           "run_case", "study_table", "read_table", "DEFAULT_WORKERS"]
