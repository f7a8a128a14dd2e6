"""``qsma run``: the full quasi-static modal analysis, results in a folder."""
from __future__ import annotations

import sys

import numpy as np

from .common import (CLI_OPTIONS, add_amplitude_argument, add_model_arguments, is_deck,
                     load_model, parse_levels_spec)
from .modes import execute_modes
from .progress import LOG_NAME

HELP = "quasi-static modal analysis: backbone, frequency and damping versus amplitude"


def add_arguments(p):
    add_model_arguments(p)
    p.add_argument("--out", required=True,
                   help="result folder, replaced as a whole by this run's files (created "
                        "if needed; refused while another run writes to it)")
    p.add_argument("--mode", type=int, help="mode index of the tied structure (default 0)")
    p.add_argument("--modes", metavar="LIST",
                   help="several modes, e.g. 0,1,2: one result folder per mode in "
                        "OUT/mode-K, OUT/modes.json and OUT/modes.vtu (docs/results.md)")
    p.add_argument("--method",
                   help="contact solver: auto, basket, active_set or nodal_gs (default "
                        "from the config or 'auto': active_set on 3D interfaces of 50 "
                        "pairs or more, basket otherwise)")
    p.add_argument("--tol", type=float, help="contact solver tolerance")
    p.add_argument("--levels", metavar="SPEC",
                   help="load levels KIND:log|linear:START:STOP:N or KIND:list:V1,V2,...; "
                        "KIND is tip (linear tied tip deflection, in the model's length "
                        "unit) or alpha (modal force), e.g. tip:log:1e-6:1e-3:51 (the "
                        "default in SI: 1 um to 1 mm; 1e-3 to 1 in a mm-N-s-tonne model)")
    p.add_argument("--maxiter", type=int, help="contact solver iteration cap")
    p.add_argument("--dissipation", choices=["auto", "masing", "loop"],
                   help="dissipation per cycle: Masing's rules where verified, none "
                        "where no pair with friction slipped, and the stabilised loop "
                        "elsewhere (auto, the default), or Masing or the loop at every "
                        "level")
    p.add_argument("--max-cycles", type=int, metavar="N",
                   help="loop cycles per amplitude before a level is declared not "
                        "stabilised (default 8; a shakedown that visibly converges gets "
                        "up to 4 times as many)")
    p.add_argument("--loop-workers", type=int, metavar="N",
                   help="processes that compute the loops (default: one per usable core "
                        "on Linux, else 1; same results for any N)")
    p.add_argument("--scheduler", dest="loop_scheduler", metavar="ADDRESS",
                   help="Dask scheduler whose workers compute the loops, e.g. "
                        "tcp://host:8786 (the interface problem is sent to each worker "
                        "once; same results as local workers)")
    p.add_argument("--direct-loop", action="store_true", default=None,
                   help="also compute the hysteresis loop directly (check of Masing)")
    p.add_argument("--continue", dest="continue_on_failure", action="store_true",
                   default=None, help="keep going after a level that does not converge")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    add_amplitude_argument(p)
    p.add_argument("--no-vtu", action="store_true", help="skip the VTU fields")
    g = p.add_mutually_exclusive_group()
    g.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    g.add_argument("-v", "--verbose", action="store_true", help="print per-level results")


def execute(args) -> int:
    from ..output.folders import RunFolder
    if args.modes is None and args.mode is None and args.config is not None \
            and not is_deck(args.config):
        from ..analysis.config import config_modes
        modes = config_modes(args.config)          # [analysis] modes = [...]
        if modes is not None:
            args.modes = ",".join(map(str, modes))
    if args.modes is not None:
        return execute_modes(args)

    worker = _plot_worker(args)
    try:
        with RunFolder(args.out) as folder:      # locked and checked before computing
            res, paths, options = _run_into(args, folder, worker)
    finally:
        if worker is not None:
            worker.close()
    out = folder.path
    if not args.quiet:
        _summary(res, paths, args.verbose)
    return _outcome(res, options, out, args.quiet)


def _plot_worker(args):
    """The process that draws the figures beside the analysis
    (:class:`qsma.output.plotworker.PlotWorker`), forked now: before the result folder's
    lock is taken (the worker holds no copy of it) and before any BLAS call. ``None``
    with ``--no-plots`` (matplotlib is never imported then) or where no worker may be
    forked (Windows, ``QSMA_PLOT_WORKER=0``): the figures are drawn in this process."""
    if args.no_plots:
        return None
    from ..output.plotworker import PlotWorker
    return PlotWorker.start()


def _run_into(args, folder, worker=None):
    """Load the model, run the analysis and write every file into ``folder`` (the
    figures by ``worker`` if given, :func:`qsma.output.files.write_all`)."""
    from ..analysis import run
    from ..output.files import write_all

    model, options = load_model(args)
    options = options.replace(**{key: getattr(args, key) for key in CLI_OPTIONS},
                              levels=None if args.levels is None
                              else parse_levels_spec(args.levels))
    log = getattr(args, "log", None)
    if log is not None:
        log.to_file(folder.staging / LOG_NAME)
    try:
        res = _with_progress(args, log, lambda bars: run(model, options, progress=bars))
    finally:
        if log is not None:
            log.close_file()            # complete before the manifest lists it
    paths = write_all(res, folder.path, plots=not args.no_plots, vtu=not args.no_vtu,
                      folder=folder, plot_worker=worker, amplitude=args.amplitude)
    return res, paths, options


def _outcome(res, options, out, quiet=False) -> int:
    """Exit code of a written run, with the warnings and failures printed."""
    dl = res.direct_loop
    if not quiet:
        _warn_flags(res)
    if dl is not None and not dl.success:
        if not options.continue_on_failure:
            print(f"qsma: analysis failed: {dl.message}; the backbone is complete in {out}",
                  file=sys.stderr)
            return 1
        print(f"qsma: warning: {dl.message}", file=sys.stderr)
    if not res.success:
        if options.continue_on_failure and not res.failed_levels:
            print(f"qsma: warning: {res.message} (continued as asked: the levels whose "
                  f"residual is above tol are flagged by 'residual' in {out})",
                  file=sys.stderr)
            return 0
        print(f"qsma: analysis failed: {res.message}; {_written(res)} in {out}",
              file=sys.stderr)
        return 1
    return 0


def _written(res) -> str:
    """What the result folder holds of a failed run: the levels solved (all of them
    unless a contact solve stopped the ramp), those with a failure flag named as such.
    ``--continue`` covers failed contact solves only: a level with a failure flag
    (:data:`qsma.analysis.result.FAILURE_FLAGS`) makes the run fail with it too."""
    if res.failed_levels:
        return f"the {res.n_levels} levels solved, the failing ones flagged ('flags'), are"
    return f"the {res.n_levels} levels solved before the failure are"


def _warn_flags(res):
    """Notes on the levels whose information flags a reader should know (the failure
    flags, with what to change, are in the run's message)."""
    by_flag = {}
    for k, flags in enumerate(res.flags):
        for f in flags:
            by_flag.setdefault(f, []).append(k)
    if "shakedown" in by_flag:
        ks = by_flag["shakedown"]
        print(f"qsma: note: the first loading (or first cycle) slipped where the settled "
              f"cycle does not (shakedown) at level(s) {ks[:12]}"
              f"{' ...' if len(ks) > 12 else ''}: q and tip are those of the first "
              f"loading, f and zeta those of the settled cycle", file=sys.stderr)
    if "hardening" in by_flag:
        ks = by_flag["hardening"]
        print(f"qsma: note: the joint stiffens (contact closing) at level(s) {ks[:12]}"
              f"{' ...' if len(ks) > 12 else ''}: damping from computed loops",
              file=sys.stderr)


def _with_progress(args, log, call):
    """``call(bars)`` with the run's progress bars on stderr (:class:`RunBars`; ``None``
    with ``--quiet`` or when stderr is not a terminal), the log messages printed above
    them while they are shown."""
    if args.quiet or not sys.stderr.isatty():
        return call(None)
    from .progress import RunBars
    with RunBars() as bars:
        if log is not None:
            log.console_handler.console = bars.console
        try:
            return call(bars)
        finally:
            if log is not None:
                log.console_handler.console = None


def _loop_costs(costs) -> str:
    """``": N loop solves, T s; the costliest at level k (n solves in c cycles, t s)"``
    of :class:`qsma.analysis.result.LevelCosts`, or "" without loops."""
    if costs is None or not np.any(costs.loop_solves):
        return ""
    k = int(np.argmax(costs.loop_seconds))
    return (f": {int(np.sum(costs.loop_solves))} loop solves, "
            f"{float(np.sum(costs.loop_seconds)):.1f} s; the costliest at level {k} "
            f"({costs.loop_solves[k]} solves in {costs.loop_cycles[k]} cycles, "
            f"{costs.loop_seconds[k]:.1f} s)")


def _summary(res, paths, verbose):
    info = res.model_info
    u = res.units
    print(f"{info['name']}: {info['n_nodes']} nodes, {info['n_pairs']} interface pairs "
          f"({info['coupling']} coupling), mu = {info['mu']}, units {u.name}")
    for body, element in info["elements"].items():
        print(f"  {body}: {element}")
    print(f"mode {res.mode_index}: f0 = {res.f0_hz:.3f} Hz; {res.n_levels} load levels, "
          f"solver {res.solver['method']}")
    n_loop = int(np.sum(res.dissipation_method == "loop"))
    n_elastic = int(np.sum(res.dissipation_method == "elastic"))
    elastic = f", {n_elastic} elastic without a loop" if n_elastic else ""
    print(f"dissipation: {res.n_levels - n_loop - n_elastic} level(s) by Masing's rules, "
          f"{n_loop} by computed loops{elastic} ({res.options.dissipation})"
          f"{_loop_costs(res.level_costs)}")
    if verbose:
        tip = f"tip [{u.length}]"
        print(f"{'k':>3} {'alpha':>11} {tip:>10} {'f [Hz]':>9} {'zeta':>10} "
              f"{'stuck':>5} {'slip':>5} {'open':>5} {'it':>4} {'solves':>6} {'s':>7}")
        c = res.level_costs
        for k in range(res.n_levels):
            print(f"{k:3d} {res.alpha[k]:11.4e} {res.tip[k]:10.3e} {res.f_hz[k]:9.3f} "
                  f"{res.zeta[k]:10.3e} {res.n_stuck[k]:5d} {res.n_slip[k]:5d} "
                  f"{res.n_open[k]:5d} {res.iterations[k]:4d} "
                  f"{c.ramp_solves[k] + c.loop_solves[k]:6d} "
                  f"{c.ramp_seconds[k] + c.loop_seconds[k]:7.2f}")
    if res.n_levels:
        print(f"last level: f = {res.f_hz[-1]:.3f} Hz, zeta = {res.zeta[-1]:.4e}, "
              f"tip = {res.tip[-1]:.3e} {u.length}")
    dl = res.direct_loop
    if dl is not None and dl.success:
        print(f"direct loop dissipation {dl.dissipation:.4e} vs Masing "
              f"{dl.dissipation_masing:.4e}")
    t = res.timings_s
    print("timings [s]: " + ", ".join(f"{k} {v:.3f}" for k, v in t.items()))
    print("results: " + ", ".join(str(p) for p in paths.values()))
