"""Time a 10-value friction sweep of sandwich-2d against 10 separate runs.

Usage: python benchmarks/bench_sweep.py [--repeat 3] [--n 10] [--levels 51]
                                        [--workers 2] [--refine 1]

Three ways of computing the same cases (mu evenly spaced from 0.2 to 0.8, the
spec's 51 load levels unless --levels says otherwise):

- ``separate``: ``qsma.run`` once per mu in this process (a user scripting runs);
- ``serial sweep``: ``qsma.sweep(..., scheduler="serial")``: assembly and
  condensation once, tied modes once per closed set, cases in order;
- ``dask sweep``: the same on a fresh ``LocalCluster`` of ``--workers`` processes
  (its start-up included, as a user pays it).

The three are interleaved in each repeat (so a change of machine load hits all
of them) and the medians are printed: wall seconds, and CPU seconds of this
process (for the Dask sweep: the sum of the cases' CPU seconds on the workers,
from their done-markers, which leaves out the cluster start-up). On a machine
shared with other jobs the wall times vary by 2x from run to run; the CPU times
are the steadier measure of the work done. The sweeps write their per-case
results.json/csv and the study table (no figures); the separate runs write nothing.
"""
import argparse
from dataclasses import replace
import glob
import json
import os
import statistics
import tempfile
import time

import numpy as np

import qsma
from qsma.examples import sandwich_2d


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--n", type=int, default=10, help="values of mu")
    ap.add_argument("--levels", type=int, default=51)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--refine", type=int, default=1)
    args = ap.parse_args()
    model = sandwich_2d(args.refine)
    mus = np.linspace(0.2, 0.8, args.n).tolist()
    opts = qsma.RunOptions(levels=qsma.Levels.log("tip", 1e-6, 1e-3, args.levels))

    def separate():
        for mu in mus:
            res = qsma.run(replace(model, mu=mu), opts)
            assert res.success, res.message

    def study(**kw):
        with tempfile.TemporaryDirectory() as d:
            res = qsma.sweep(model, {"mu": mus}, opts, out=d, plots=False, **kw)
            assert res.success, res.message
            return sum(json.load(open(f))["cpu_seconds"]
                       for f in glob.glob(os.path.join(d, "case-*.done.json")))

    ways = {"separate runs": separate,
            "serial sweep": lambda: study(scheduler="serial"),
            f"dask sweep, {args.workers} workers": lambda: study(workers=args.workers)}
    res = qsma.run(model, opts)
    t = res.timings_s
    shared = t["model"] + t["assembly"] + t["condensation"] + t["modal"]
    print(f"sandwich-2d refine {args.refine}, {args.n} values of mu, {args.levels} levels, "
          f"median of {args.repeat}; one run: {t['total']:.2f} s of which {shared:.2f} s "
          f"pairing/assembly/condensation/modes (shareable), {t['contact']:.2f} s contact "
          f"ramps; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    wall = {k: [] for k in ways}
    cpu = {k: [] for k in ways}
    for _ in range(args.repeat):
        for name, fn in ways.items():
            w0, c0 = time.perf_counter(), time.process_time()
            worker_cpu = fn()
            wall[name].append(time.perf_counter() - w0)
            cpu[name].append(worker_cpu if name.startswith("dask") else
                             time.process_time() - c0)
    ref_w, ref_c = statistics.median(wall["separate runs"]), \
        statistics.median(cpu["separate runs"])
    print("| way | wall s | speed-up (wall) | CPU s | speed-up (CPU) |")
    print("|---|---|---|---|---|")
    for name in ways:
        w, c = statistics.median(wall[name]), statistics.median(cpu[name])
        print(f"| {name} | {w:.2f} | {ref_w / w:.2f}x | {c:.2f} | {ref_c / c:.2f}x |")
    print(f"load average after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
