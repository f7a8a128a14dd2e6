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

Cases run on Dask (:mod:`distributed`): a :class:`distributed.LocalCluster` of
processes by default, any scheduler by address, or serially in this process
(``scheduler="serial"``). Each case writes a folder as ``qsma run`` does
(:func:`qsma.results.write_all`) and then a done-marker; a study started again in the
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

import numpy as np

from ..errors import InputError, QSMAError
from ..levels import Levels
from ..options import RunOptions
from ..rundir import MANIFEST, StudyFolder

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
#: this package is developed on; ``workers=`` or ``--workers`` changes it.
DEFAULT_WORKERS = 2
CASE_FILES = ("plots", "vtu", "rom", "report")
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
                values = np.linspace(start, stop, n).tolist()
            elif len(parts) == 1:
                values = [_scalar(v) for v in spec.split(",") if v.strip()]
            else:
                raise ValueError
        except ValueError:
            raise InputError(f"--vary {name}={spec!r}: expected START:STOP:N (e.g. "
                             f"0.2:0.8:10) or a list V1,V2,... (e.g. 0.3,0.5,0.7)") from None
    if not values:
        raise InputError(f"--vary {name}: no values given")
    return [_typed(name, v) for v in values]


def grid(vary: dict) -> list:
    """The cases of the cartesian product of ``vary`` (name -> values or spec), the last
    parameter varying fastest."""
    if not vary:
        raise InputError("a sweep needs at least one parameter to vary, e.g. "
                         "vary={'mu': [0.3, 0.5]} or --vary mu=0.3,0.5")
    names = list(vary)
    values = [parse_values(n, vary[n]) for n in names]
    return [Case(i, tuple(zip(names, combo)))
            for i, combo in enumerate(itertools.product(*values))]


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
            raise InputError(f"sweep parameter {name!r}: no body {body!r}; bodies: {names}")
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
    from ..results import atomic_write, write_all
    t0, c0 = time.perf_counter(), time.process_time()
    params = case.as_dict()
    status, message = "ok", "all levels converged"
    try:
        res = run_prepared(*case_inputs(prepared, params, options))
        write_all(res, folder, plots="plots" in files, vtu="vtu" in files,
                  report="report" in files)
        if "rom" in files and res.n_levels:
            from ..rom import export_rom
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
          scheduler=None, workers: int = DEFAULT_WORKERS, files=(), plots=True,
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
    scheduler : None, "serial", str or distributed.Client
        ``None``: a local cluster of ``workers`` processes; ``"serial"`` (or
        ``workers=0``): in this process, in order; an address (``tcp://host:8786``)
        or a client: that scheduler (the workers must see ``out``).
    workers : int
        Processes of the local cluster.
    files : iterable of {"plots", "vtu", "rom", "report"}
        Per-case files besides results.json and results.csv (rom: :mod:`qsma.rom`,
        written beside the case folder as ``case-NNNN.rom.json``; report: the case's
        report.html, :mod:`qsma.report`).
    plots : bool
        Study figures (frequency and damping versus amplitude per parameter); the
        study's report.html is written in any case.
    progress : callable, optional
        ``progress(done, total)`` after each case (skipped ones included).
    amplitude : str, optional
        The amplitude measure of the study figures (:data:`qsma.plots.AMPLITUDES`,
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
    if amplitude is not None:
        from ..plots import check_amplitude
        check_amplitude(amplitude)
    if not (isinstance(workers, int) and workers >= 0):
        raise InputError(f"workers must be an integer >= 0, got {workers!r}")
    cases = grid(vary)
    _check_bodies(cases, model)
    with StudyFolder(out, allowed=_in_study) as folder:   # locked before computing
        return _study(folder, model, vary, options, cases, scheduler, workers, files,
                      plots, progress, t0, amplitude)


def _study(folder, model, vary, options, cases, scheduler, workers, files, plots, progress,
           t0, amplitude=None) -> SweepResult:
    """:func:`sweep` in its entered :class:`qsma.rundir.StudyFolder` (manifest written
    when every case is done)."""
    from ..results import atomic_write
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
    serial = scheduler == "serial" or (scheduler is None and workers == 0)
    run = _run_serial if serial else _run_dask
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
    from ..report import REPORT_NAME, write_study_report
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


# ------------------------------------------------- shipping a preparation to workers

@dataclass(frozen=True, eq=False)
class ShippedPreparation:
    r"""A :class:`qsma.analysis.Prepared` sent to Dask workers with its condensed model.

    A ``Prepared`` pickled on its own keeps the model, pairing and assembled bodies
    and condenses again where it is unpickled (its factorisations cannot be pickled):
    every worker then repeated the Schur complements and the two-body combination of
    the preparation. Pickled through this wrapper it keeps the condensed model as
    computed here (``K``, ``W``, the condensed loads and functionals, the factor of
    the welded pair, each body's ``Kc``), and each body's factorised
    :math:`K_{EE}^{-1}` is replaced by :class:`RefactorisedEE`, which factorises
    :math:`K_{EE}` of the shipped assembled body the first time a solve is asked for
    (the tied modes, the modal load, the fields) and keeps the factor. A worker thus
    does one sparse factorisation per body instead of the whole condensation, and
    every number it starts from is the one the study computed.

    Unpickling gives the ``Prepared`` itself (with an empty cache).
    """

    prepared: object

    def __reduce__(self):
        p = self.prepared
        bodies = _refactorised_bodies(p.reduced.bodies, p.assembled)
        return (_arrived, (p.model, p.pairing, p.assembled,
                           replace(p.reduced, bodies=bodies), p.preload_scale,
                           p.schur_backend, p.timings_s))


def _refactorised_bodies(bodies, assembled) -> tuple:
    """The condensed bodies with each own ``K_EE`` factor replaced by a
    :class:`RefactorisedEE`; a body that solves through a congruent body's factor
    (:class:`qsma.congruence.MappedSolver`) keeps doing so, through that body's
    ``RefactorisedEE`` (one object, pickled once: one factorisation per worker)."""
    from ..congruence import MappedSolver
    by_name = {a.body.name: a for a in assembled}
    own = {b.name: RefactorisedEE(by_name[b.name], b.E, _backend_of(b.solve_EE))
           for b in bodies if not isinstance(b.solve_EE, MappedSolver)}
    return tuple(replace(b, solve_EE=replace(b.solve_EE, base=own[b.solve_EE.base_name])
                         if isinstance(b.solve_EE, MappedSolver) else own[b.name])
                 for b in bodies)


def _backend_of(solver) -> str:
    """The factorisation backend of a ``K_EE`` solver (``"auto"`` if it does not say)."""
    return getattr(solver, "backend", "auto")


def _arrived(model, pairing, assembled, reduced, preload_scale, schur_backend, timings):
    from ..analysis import Prepared
    return Prepared(model, pairing, assembled, reduced, preload_scale, schur_backend,
                    timings, {})


class RefactorisedEE:
    r"""``x = K_EE^{-1} b`` of one body, factorised on first use.

    ``K_EE = K[E][:, E]`` with ``K`` the assembled stiffness of ``assembled`` and ``E``
    the body's non-interface free DOFs (:attr:`qsma.condense.CondensedBody.E`), the
    block whose factor the condensation used. The factorisation is
    :func:`qsma.linalg.spd_solver` with the condensation's ``backend`` where it names
    one it knows (its fill-reducing ordering may differ from the condensation's, so
    solves agree with the original factor to round-off, not bit for bit). Accepts
    ``b`` of shape ``(n_E,)`` or ``(n_E, k)``.
    """

    def __init__(self, assembled, E, backend="auto"):
        self.assembled, self.E, self.backend = assembled, np.asarray(E), backend
        self._solve = None
        self._lock = threading.Lock()

    @property
    def n(self) -> int:
        return len(self.E)

    @property
    def factorised(self) -> bool:
        return self._solve is not None

    def __call__(self, b):
        from ..linalg import ee_rhs, spd_solver
        b = ee_rhs(b, self.n)
        if b.size == 0:
            return b.copy()
        with self._lock:
            if self._solve is None:
                K = self.assembled.K.tocsr()
                self._solve = spd_solver(K[self.E][:, self.E], backend=self.backend)
        return self._solve(b)

    def __reduce__(self):                 # shipped again (e.g. spilled): refactorised
        return (RefactorisedEE, (self.assembled, self.E, self.backend))

    def __repr__(self):
        return (f"RefactorisedEE(n={self.n}, backend={self.backend!r}, "
                f"factorised={self.factorised})")


def _run_serial(groups, key_of, todo, options, out, files, scheduler, workers):
    for c in todo:
        yield run_case(groups[key_of(c)], c, options, out / c.name, files)


def _run_dask(groups, key_of, todo, options, out, files, scheduler, workers):
    """Cases as Dask tasks; each group's preparation is scattered once to every
    worker with its condensed model (:class:`ShippedPreparation`: no condensation on
    the workers, one ``K_EE`` factorisation per body and worker when first needed)."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError as exc:      # dask is the optional extra 'sweep'
        raise InputError(f"parallel sweeps need the 'distributed' package ({exc}): "
                         f"pip install 'qsma[sweep]', or run the cases one after the "
                         f"other with scheduler='serial' (--workers 0)") from None
    cluster = None
    if scheduler is None:
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
        except OSError as exc:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}; "
                             f"start one (dask scheduler) or drop --scheduler") from None
    else:
        client = scheduler
    try:
        shared = {k: client.scatter(ShippedPreparation(p), broadcast=True, hash=False)
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
    run's results.csv (:func:`qsma.results.csv_columns`)."""
    from ..results import csv_columns
    return ("case",) + tuple(parameters) + ("status", "message") + csv_columns()


def study_table(cases, outcomes, out) -> dict:
    """Column name -> list, a row per case and level, read from the case folders
    (a case without levels has one row with empty level values)."""
    from ..results import csv_columns
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
    from ..results import atomic_path, atomic_write, _csv_cell
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
    from ..results import column_name
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return {column_name(name): [r[i] for r in rows[1:]] for i, name in enumerate(rows[0])}


__all__ = ["sweep", "grid", "parse_values", "Case", "CaseOutcome", "SweepResult",
           "run_case", "study_table", "read_table", "DEFAULT_WORKERS"]
