"""``qsma sweep``: a parameter study, cases in parallel on Dask, one table."""
from __future__ import annotations

import sys

from ..errors import InputError
from .common import add_amplitude_argument, add_model_arguments, load_model, parse_levels_spec

HELP = ("parameter study: QSMA over a grid of friction, preload scale, materials, mode "
        "or levels, sharing assembly and condensation; cases run on Dask")


def add_arguments(p):
    add_model_arguments(p)
    p.add_argument("--vary", action="append", required=True, metavar="NAME=VALUES",
                   help="a parameter and its values: NAME=START:STOP:N or NAME=V1,V2,...; "
                        "NAME is mu, preload (scale of the bolt pressures), E, nu, rho "
                        "(E:BODY for one body), mode, levels (specs separated by ';') "
                        "or another run option; repeat for a grid (cartesian product)")
    p.add_argument("--out", required=True, help="study folder (created; resumed if it "
                                                "holds this study)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes that run the cases (default 2, at most the usable "
                        "cores), forked from this one (where it may not fork: a local "
                        "Dask cluster); 0 runs the "
                        "cases one after the other in this process")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler to run on, e.g. tcp://host:8786 (its workers "
                        "must see --out), or 'dask' for a local Dask cluster of "
                        "--workers processes")
    p.add_argument("--levels", metavar="SPEC", help="load levels of every case "
                                                    "(as qsma run --levels)")
    p.add_argument("--mode", type=int, help="mode index of every case")
    p.add_argument("--method", help="contact solver of every case")
    p.add_argument("--case-files", default="", metavar="KINDS",
                   help="per-case files besides results.json/csv: plots, vtu, rom "
                        "(rom.json: a fitted modal Iwan model), report (report.html)")
    p.add_argument("--no-plots", action="store_true", help="skip the study figures")
    add_amplitude_argument(p)
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")


def parse_vary(items) -> dict:
    """``["mu=0.2:0.8:10", ...]`` -> ``{"mu": "0.2:0.8:10", ...}`` (values parsed later)."""
    out = {}
    for item in items:
        name, sep, values = item.partition("=")
        if not sep or not name or not values:
            raise InputError(f"--vary {item!r}: expected NAME=VALUES, e.g. mu=0.2:0.8:10 "
                             f"or mu=0.3,0.5,0.7")
        if name in out:
            raise InputError(f"--vary {name} given twice; give all its values in one "
                             f"--vary (e.g. {name}=0.3,0.5)")
        out[name] = values
    return out


def execute(args) -> int:
    from ..study import sweep
    if args.workers is not None and args.workers < 0:
        raise InputError(f"--workers must be >= 0, got {args.workers}")
    if args.scheduler and args.workers is not None:
        raise InputError("--workers sets up a local cluster; with --scheduler the "
                         "scheduler's workers are used: give one of them")
    vary = parse_vary(args.vary)
    if "levels" in vary:
        vary["levels"] = [parse_levels_spec(s) for s in vary["levels"].split(";") if s]
    files = tuple(f for f in args.case_files.split(",") if f)
    model, options = load_model(args)
    options = options.replace(mode=args.mode, method=args.method,
                              levels=None if args.levels is None
                              else parse_levels_spec(args.levels))
    workers = args.workers
    scheduler = args.scheduler or ("serial" if workers == 0 else None)
    call = lambda progress: sweep(model, vary, options, out=args.out, scheduler=scheduler,
                                  workers=workers, files=files, plots=not args.no_plots,
                                  progress=progress, amplitude=args.amplitude)
    if args.quiet or not sys.stderr.isatty():
        res = call(None)
    else:
        from .progress import CountBar
        with CountBar("qsma: cases") as bar:
            res = call(bar)
    if not args.quiet:
        print(f"{len(res.cases)} cases over {', '.join(res.parameters)} "
              f"({res.n_skipped} already done); {res.timings_s['total']:.1f} s")
        print("results: " + ", ".join(str(p) for p in res.paths.values()))
    if not res.success:
        print(f"qsma: warning: {res.message}", file=sys.stderr)
        return 1
    return 0

