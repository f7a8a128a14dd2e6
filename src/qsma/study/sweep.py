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

from dataclasses import dataclass, field
import json
import re
import time

from ..errors import InputError
from ..analysis.levels import Levels
from ..analysis.options import EXECUTION_FIELDS, RunOptions
from ..output.folders import MANIFEST, StudyFolder
from .cases import Case, check_bodies, grid, material_key, parse_values
from .runners import (DONE_SUFFIX, CaseOutcome, check_scheduler, check_workers,
                      choose_runner, json_roundtrip, prepare_groups, recorded_outcome,
                      run_case)
from .table import PARQUET_NAME, TABLE_NAME, read_table, study_table, write_table

#: The study's record in its folder (docs/studies.md describes it, and the table's files).
STUDY_NAME = "study.json"
#: Workers of the default local cluster: one process per core of the 2-core machines
#: this package is developed on (fewer where fewer cores are usable); ``workers=`` or
#: ``--workers`` changes it, up to the usable cores.
DEFAULT_WORKERS = 2
CASE_FILES = ("plots", "vtu", "rom", "report")
#: Run options left out of a study's fingerprint: they change no result
#: (:data:`qsma.analysis.options.EXECUTION_FIELDS`), so a study resumes whatever they are.
NOT_FINGERPRINTED = EXECUTION_FIELDS


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


# --------------------------------------------------------------------------- the study

def sweep(model_or_config, vary: dict, options: RunOptions | None = None, *, out,
          scheduler=None, workers: int | None = None, files=(), plots=True,
          progress=None, amplitude=None) -> SweepResult:
    """Run a parameter study: every case of the grid ``vary``, sharing the work the
    cases have in common (module docstring), on Dask or serially.

    Parameters
    ----------
    model_or_config : :class:`qsma.model.Model` or :class:`qsma.analysis.config.RunConfig`
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
    from ..analysis.config import RunConfig
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
    check_workers(workers, scheduler)
    cases = grid(vary, n_levels=_most_levels(vary, options))
    check_bodies(cases, model)
    check_scheduler(scheduler)
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
        done = recorded_outcome(c, out / c.name)
        if done is None:
            todo.append(c)
        else:
            outcomes[c.index] = done
    n_total = len(cases)
    if progress is not None:
        progress(len(outcomes), n_total)
    t_prep = time.perf_counter()
    groups = prepare_groups(model, options, todo) if todo else {}
    t_prep = time.perf_counter() - t_prep
    names = [b.name for b in model.bodies]
    key_of = lambda c: material_key(c, len(model.bodies), names)
    run = choose_runner(scheduler, workers, len(todo))
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


def _most_levels(vary, options) -> int:
    """The most load levels a case of the study has (its levels, or the default 51)."""
    from ..analysis.levels import spec_levels
    given = [v for v in vary.get("levels", ()) if isinstance(v, Levels)] \
        if not isinstance(vary.get("levels", ()), str) else []
    levels = given + [options.levels or spec_levels()]
    return max(len(lv.values) for lv in levels)


# ---------------------------------------------------------------- the study folder

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
    if old.get("cases") != json_roundtrip(study["cases"]):
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


__all__ = ["sweep", "grid", "parse_values", "Case", "CaseOutcome", "SweepResult",
           "run_case", "study_table", "read_table", "DEFAULT_WORKERS", "STUDY_NAME",
           "TABLE_NAME", "PARQUET_NAME", "DONE_SUFFIX"]

# What moved to the modules beside this one (the cases, their runners, the table) stays
# reachable here for one release, with a DeprecationWarning.
from .._infra.deprecation import forward  # noqa: E402

forward(__name__, "qsma.study.cases", "qsma.study.runners", "qsma.study.table")
