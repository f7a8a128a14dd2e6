"""Where and how the cases of a study run: one case (:func:`run_case`: run from its
group's preparation, written as ``qsma run`` writes, then marked done), and the
runners that take a list of them: in this process (:func:`run_serial`), on processes
forked from this one (:func:`run_forked`), on Dask (:func:`run_dask`);
:func:`choose_runner` picks one (docs/studies.md)."""
from __future__ import annotations

from dataclasses import dataclass
import json
import logging
from pathlib import Path
import time
import warnings

from .._infra.shipping import InBand
from ..errors import InputError, QSMAError, SerialSweepWarning
from ..analysis.options import RunOptions
from .cases import Case, case_inputs, material_key, model_with_materials

log = logging.getLogger("qsma")

#: Written beside a case folder (``case-0003.done.json``) once the case is finished:
#: its presence marks the case as done. Outside the folder, so that the folder is
#: exactly what ``qsma run`` writes (a result folder holds one run and nothing else).
DONE_SUFFIX = ".done.json"


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


def prepare_groups(model, options, cases):
    """One :class:`qsma.analysis.Prepared` per distinct set of material constants;
    bodies whose constants are those of another group reuse its assembly."""
    from ..analysis import prepare
    names = [b.name for b in model.bodies]
    groups, by_body = {}, {}
    for case in cases:
        key = material_key(case, len(model.bodies), names)
        if key in groups:
            continue
        m = model_with_materials(model, key)
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


def done_path(folder) -> Path:
    """The done-marker of the case folder ``folder``: ``<folder>.done.json``."""
    folder = Path(folder)
    return folder.with_name(folder.name + DONE_SUFFIX)


def recorded_outcome(case, folder):
    """The outcome recorded in ``folder`` for ``case``, or None if it is to be run: no
    marker, a failed case (a failure may be passing, e.g. a full disk: retried), or a
    marker whose result folder is gone."""
    path = done_path(folder)
    if not path.exists():
        return None
    marker = json.loads(path.read_text())
    if marker.get("status") == "failed" or not (Path(folder) / "results.json").exists():
        return None
    if marker.get("params") != json_roundtrip(case.json_params()):
        raise InputError(f"{path} records parameters {marker.get('params')} but case "
                         f"{case.index} of this study is {case.json_params()}: the folder "
                         f"holds another study; choose another output folder")
    return CaseOutcome(case.index, case.as_dict(), marker["status"], marker["message"],
                       marker["seconds"], str(folder), skipped=True)


def json_roundtrip(x):
    return json.loads(json.dumps(x))


# ------------------------------------------------------------------------ the runners

def distributed_available() -> bool:
    """Whether Dask's ``distributed`` (the extra ``sweep``) can be imported."""
    import importlib.util
    try:
        return importlib.util.find_spec("distributed") is not None
    except (ImportError, ValueError):       # a module set to None in sys.modules
        return False


def choose_runner(scheduler, workers, n_todo):
    """How the cases run (module docstring): in this process (``"serial"``, or no
    scheduler and ``workers == 0``); on ``workers`` processes forked from this one (no
    scheduler: :func:`run_forked`), or where this process may not fork on a local
    Dask cluster, or without Dask in this process with a
    :class:`qsma.errors.SerialSweepWarning`; on Dask (``"dask"``: a local cluster, an
    address or a client: :func:`run_dask`)."""
    from .._infra.forked import fork_refusal
    if scheduler == "serial" or (scheduler is None and workers == 0) or n_todo == 0:
        return run_serial
    if scheduler is not None:
        return run_dask
    why_not = fork_refusal()
    if why_not is None:
        return run_forked
    if distributed_available():
        log.info("cases on a local Dask cluster, not on forked processes: %s", why_not)
        return run_dask
    warnings.warn(f"the {n_todo} case(s) run one after the other in this process: it "
                  f"may not fork workers ({why_not}) and the 'distributed' package is not "
                  f"installed (for a local cluster of {workers} workers: pip install "
                  f"'qsma[sweep]')", SerialSweepWarning, stacklevel=3)
    return run_serial


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
#: results are the same bits either way, docs/performance.md "How it uses the cores").
FORKED_CASE_OPTIONS = dict(loop_workers=1, parallel_ramps=False)


def run_forked(groups, key_of, todo, options, out, files, scheduler, workers):
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


def check_workers(workers, scheduler):
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


def check_scheduler(scheduler):
    """Refuse, before any work, a scheduler address that is not one (the connection
    itself is tried when the cases are sent)."""
    if not isinstance(scheduler, str) or scheduler == "serial":
        return
    try:
        from distributed.comm import parse_address
        from distributed.comm.addressing import parse_host_port
    except ImportError:
        return                          # said when the cases are sent (run_dask)
    try:
        protocol, location = parse_address(scheduler)
        if protocol in ("tcp", "tls", "ws", "wss"):
            parse_host_port(location)
    except (ValueError, TypeError) as exc:
        raise InputError(f"--scheduler {scheduler!r} is not a Dask scheduler address "
                         f"({exc}); give one such as tcp://host:8786, or drop --scheduler "
                         f"to run on a local cluster") from None


def run_serial(groups, key_of, todo, options, out, files, scheduler, workers):
    for c in todo:
        yield run_case(groups[key_of(c)], c, options, out / c.name, files)


def run_dask(groups, key_of, todo, options, out, files, scheduler, workers):
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
        shared = {k: client.scatter(InBand(p), broadcast=True, hash=False)
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
