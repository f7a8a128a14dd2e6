"""Time a 10-value friction sweep of sandwich-2d against 10 separate runs.

Usage: python benchmarks/bench_sweep.py [--repeat 3] [--n 10] [--levels 51]
                                        [--workers 2] [--refine 1]

Three ways of computing the same cases (mu evenly spaced from 0.2 to 0.8, the
spec's 51 load levels unless --levels says otherwise), each the median of
``--repeat`` runs in this process:

- ``separate``: ``qsma.run`` once per mu (what a user scripting runs would do);
- ``serial sweep``: ``qsma.sweep(..., scheduler="serial")``: the assembly and
  condensation once, the tied modes once per closed set, cases in order;
- ``dask sweep``: the same on a fresh two-worker ``LocalCluster`` (its start-up is
  included, as a user pays it).

The sweeps write their per-case results.json/csv and the study table (no
figures); the separate runs write nothing. Printed: a markdown table and the
per-case split of a run (shareable work versus the rest).
"""
import argparse
from dataclasses import replace
import statistics
import tempfile
import time

import numpy as np

import qsma
from qsma.examples import sandwich_2d


def timed(fn, repeat):
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


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
        def go():
            with tempfile.TemporaryDirectory() as d:
                res = qsma.sweep(model, {"mu": mus}, opts, out=d, plots=False, **kw)
                assert res.success, res.message
        return go

    res = qsma.run(model, opts)
    t = res.timings_s
    shared = t["model"] + t["assembly"] + t["condensation"] + t["modal"]
    print(f"sandwich-2d refine {args.refine}, {args.n} values of mu, {args.levels} levels, "
          f"median of {args.repeat}; one run: {t['total']:.2f} s of which "
          f"{shared:.2f} s pairing/assembly/condensation/modes (shareable), "
          f"{t['contact']:.2f} s contact ramps")
    rows = [("separate runs", timed(separate, args.repeat))]
    rows.append(("serial sweep", timed(study(scheduler="serial"), args.repeat)))
    rows.append((f"dask sweep, {args.workers} workers",
                 timed(study(workers=args.workers), args.repeat)))
    print("| way | seconds | speed-up vs separate |")
    print("|---|---|---|")
    for name, s in rows:
        print(f"| {name} | {s:.2f} | {rows[0][1] / s:.2f}x |", flush=True)


if __name__ == "__main__":
    main()
