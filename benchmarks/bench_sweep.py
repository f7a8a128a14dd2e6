"""Time a parameter study against separate runs: a friction sweep of sandwich-2d, or a
friction x preload grid of sandwich-3d on 1 and 2 Dask workers.

Usage: python benchmarks/bench_sweep.py [--repeat 3] [--n 10] [--levels 51]
           [--example sandwich-2d|sandwich-3d] [--refine 1] [--preload 0]
           [--workers 2 [2 ...]] [--ways separate,serial,forked,dask]

The cases: ``--n`` values of mu evenly spaced from 0.2 to 0.8, times ``--preload``
values of the preload scale from 0.5 to 1.5 when it is given (the 4 x 5 grid of
issue 15: ``--example sandwich-3d --n 4 --preload 5``), on the spec's 51 load levels
unless --levels says otherwise. Ways of computing the same cases (``--ways``):

- ``separate``: ``qsma.run`` once per case in this process (a user scripting runs);
- ``serial``: ``qsma.sweep(..., scheduler="serial")``: assembly and condensation
  once, preload once per case, tied modes once per closed set, cases in order;
- ``forked``: the same on ``--workers`` processes forked from this one (``qsma sweep
  --workers N``, the default): the preparation is inherited, nothing is pickled;
- ``dask``: the same on a fresh ``LocalCluster`` of each ``--workers`` count (its
  start-up included, as a user pays it; ``scheduler="dask"``).

The ways are interleaved in each repeat (so a change of machine load hits all of
them) and the medians are printed: wall seconds, CPU seconds of the cases (this
process's for the separate runs and a serial sweep; for a forked or Dask sweep the sum of the
cases' CPU seconds on the workers, from their done-markers, which leaves out the
cluster start-up and what a worker does when the shared preparation arrives), and
the CPU seconds of every process (this one and all its children once they have
ended: the Dask nannies and workers with their start-up, the unpickling of the
preparation, the cases and the shut-down). On a machine shared with other jobs the
wall times vary by 2x from run to run; the CPU times are the steadier measure of the
work done. The sweeps write their per-case results.json/csv, the study table and
report.html (no figures); the separate runs write nothing.
"""
import argparse
from dataclasses import replace
import glob
import itertools
import json
import os
import resource
import statistics
import tempfile
import time

import numpy as np

import qsma
from qsma.examples import EXAMPLES


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--n", type=int, default=10, help="values of mu")
    ap.add_argument("--preload", type=int, default=0, help="values of the preload scale "
                                                           "(0: not varied)")
    ap.add_argument("--levels", type=int, default=51)
    ap.add_argument("--workers", type=int, nargs="+", default=[2])
    ap.add_argument("--example", default="sandwich-2d", choices=sorted(EXAMPLES))
    ap.add_argument("--refine", type=int, default=1)
    ap.add_argument("--ways", default="separate,serial,forked,dask")
    args = ap.parse_args()
    model = EXAMPLES[args.example](args.refine)
    vary = {"mu": np.linspace(0.2, 0.8, args.n).tolist()}
    if args.preload:
        vary["preload"] = np.linspace(0.5, 1.5, args.preload).tolist()
    cases = list(itertools.product(*vary.values()))
    opts = qsma.RunOptions(levels=qsma.Levels.log("tip", 1e-6, 1e-3, args.levels))

    def separate():
        for values in cases:
            params = dict(zip(vary, values))
            m = replace(model, mu=params["mu"])
            if "preload" in params:
                m = scaled(m, params["preload"])
            res = qsma.run(m, opts)
            assert res.success, res.message

    def study(**kw):
        with tempfile.TemporaryDirectory() as d:
            res = qsma.sweep(model, vary, opts, out=d, plots=False, **kw)
            assert res.success, res.message
            return sum(json.load(open(f))["cpu_seconds"]
                       for f in glob.glob(os.path.join(d, "case-*.done.json")))

    chosen = args.ways.split(",")
    ways = {}
    if "separate" in chosen:
        ways["separate runs"] = separate
    if "serial" in chosen:
        ways["serial sweep"] = lambda: study(scheduler="serial")
    if "forked" in chosen:
        for w in args.workers:
            ways[f"forked sweep, {w} worker(s)"] = lambda w=w: study(workers=w)
    if "dask" in chosen:
        for w in args.workers:
            ways[f"dask sweep, {w} worker(s)"] = lambda w=w: study(workers=w,
                                                                   scheduler="dask")
    res = qsma.run(model, opts)
    t = res.timings_s
    shared = t["model"] + t["assembly"] + t["condensation"] + t["modal"]
    print(f"{args.example} refine {args.refine}, {len(cases)} cases over {list(vary)}, "
          f"{args.levels} levels, median of {args.repeat}; one run: {t['total']:.2f} s of "
          f"which {shared:.2f} s pairing/assembly/condensation/modes (shareable), "
          f"{t['contact']:.2f} s contact ({res.solver['backbone_points']} backbone points); "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    wall = {k: [] for k in ways}
    cpu = {k: [] for k in ways}
    total = {k: [] for k in ways}
    for _ in range(args.repeat):
        for name, fn in ways.items():
            w0, c0, a0 = time.perf_counter(), time.process_time(), children_cpu()
            worker_cpu = fn()
            wall[name].append(time.perf_counter() - w0)
            own = time.process_time() - c0
            cpu[name].append(worker_cpu if name.startswith(("dask", "forked")) else own)
            total[name].append(own + children_cpu() - a0)
    first = next(iter(ways))
    ref_w, ref_c = statistics.median(wall[first]), statistics.median(cpu[first])
    ref_t = statistics.median(total[first])
    print(f"| way | wall s | speed-up (wall) | CPU s of the cases | speed-up (CPU) | "
          f"CPU s, all processes | speed-up |  (against {first})")
    print("|---|---|---|---|---|---|---|")
    for name in ways:
        w, c = statistics.median(wall[name]), statistics.median(cpu[name])
        t = statistics.median(total[name])
        print(f"| {name} | {w:.2f} | {ref_w / w:.2f}x | {c:.2f} | {ref_c / c:.2f}x | "
              f"{t:.2f} | {ref_t / t:.2f}x |")
    print(f"load average after: {os.getloadavg()[0]:.1f}")


def children_cpu():
    """User + system CPU seconds of this process's children (and theirs) that have
    ended and been waited for."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def scaled(model, s):
    """The model with every 'preload' pressure multiplied by ``s`` (assembled anew)."""
    from qsma.model import Pressure
    return replace(model, bodies=tuple(replace(b, pressures=tuple(
        Pressure(p.set, p.p * s, p.load) if p.load == "preload" else p
        for p in b.pressures)) for b in model.bodies))


if __name__ == "__main__":
    main()
