"""The Brake-Reuss beam (qsma.examples.brb): tied frequency and cost per mesh.

Usage: python benchmarks/bench_brb.py [--refine 1 2 3] [--repeats 3]
       python benchmarks/bench_brb.py --run [--refine 2] [--repeats 3]

Per refinement: nodes, interface pairs, pairs closed by the preload, the tied
free-free frequencies of the first two elastic modes (bending along the bolt axis,
then across the width), the relative equilibrium error of the preload (sum of the
contact pressures against the three bolts' pretension), and the median wall
seconds of preparation (assembly and condensation), preload and tied modes over
``--repeats`` runs. Refine 3 needs about 3 GB and a minute per repeat; refine 4
about 6 GB (not run by default).

``--run`` times the whole validation run instead, the command line
``qsma run --example brb --refine R --levels tip:log:1e-6:1e-3:13 --out DIR --no-vtu``
in a child process (wall seconds, and the child's CPU seconds from the operating
system), with the hysteresis stage and the loop solves from its results.json, and
prints the medians over ``--repeats`` runs with the load average before and after
(the machine is shared: compare versions in the same session, alternating).
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

from qsma.analysis import StageClock, prepare
from qsma.contact import OPEN
from qsma.examples.brb import brb
from qsma.analysis.options import RunOptions


def one(refine):
    """``(row of numbers, seconds per stage)`` of one tied analysis."""
    t0 = time.perf_counter()
    p = prepare(brb(refine))
    t1 = time.perf_counter()
    _, _, pre = p.preloaded(RunOptions(), StageClock())
    t2 = time.perf_counter()
    closed = pre.status != OPEN
    modes = p.mode(closed, RunOptions(n_modes=2), StageClock())[0].result()
    t3 = time.perf_counter()
    n0 = sum(b.pretension for b in p.model.bolts)
    row = dict(nodes=sum(b.mesh.n_nodes for b in p.model.bodies), pairs=p.pairing.n_pairs,
               closed=int(closed.sum()), f1=modes.f_hz[modes.n_rigid],
               f2=modes.f_hz[modes.n_rigid + 1],
               eq=abs(pre.lam[:, -1].sum() / n0 - 1))
    return row, (t1 - t0, t2 - t1, t3 - t2)


LEVELS = "tip:log:1e-6:1e-3:13"


def whole_run(refine):
    """``(wall s, CPU s, hysteresis s, loop solves)`` of one command-line run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "qsma", "run", "--example", "brb", "--refine",
                        str(refine), "--levels", LEVELS, "--out", out, "--no-vtu"],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        with open(os.path.join(out, "results.json")) as f:
            res = json.load(f)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, res["timings_s"]["hysteresis"], res["solver"]["loop_solves"]


def main_run(refines, repeats):
    print(f"load average before: {os.getloadavg()[0]:.1f}")
    print(f"{'refine':>6} {'wall [s]':>9} {'CPU [s]':>8} {'hysteresis [s]':>15} "
          f"{'loop solves':>11}   (medians of {repeats})")
    for r in refines:
        runs = np.array([whole_run(r) for _ in range(repeats)])
        med = np.median(runs, axis=0)
        print(f"{r:>6} {med[0]:>9.1f} {med[1]:>8.1f} {med[2]:>15.1f} {int(med[3]):>11}"
              f"   wall {', '.join(f'{w:.0f}' for w in runs[:, 0])}; "
              f"CPU {', '.join(f'{c:.0f}' for c in runs[:, 1])}", flush=True)
    print(f"load average after: {os.getloadavg()[0]:.1f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, nargs="+", default=None)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--run", action="store_true",
                    help="time the whole validation run (command line) instead")
    args = ap.parse_args(argv)
    if args.run:
        return main_run(args.refine or [2], args.repeats)
    args.refine = args.refine or [1, 2]
    print(f"{'refine':>6} {'nodes':>7} {'pairs':>6} {'closed':>6} {'f1 [Hz]':>10} "
          f"{'f2 [Hz]':>10} {'equil.':>8} {'prepare':>8} {'preload':>8} {'modes':>7}")
    for r in args.refine:
        runs = [one(r) for _ in range(args.repeats)]
        row = runs[0][0]
        med = np.median([s for _, s in runs], axis=0)
        print(f"{r:>6} {row['nodes']:>7} {row['pairs']:>6} {row['closed']:>6} "
              f"{row['f1']:>10.4f} {row['f2']:>10.4f} {row['eq']:>8.1e} "
              f"{med[0]:>8.2f} {med[1]:>8.2f} {med[2]:>7.2f}", flush=True)


if __name__ == "__main__":
    main()
