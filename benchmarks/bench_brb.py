"""The Brake-Reuss beam (qsma.examples.brb): tied frequency and cost per mesh.

Usage: python benchmarks/bench_brb.py [--refine 1 2 3] [--repeats 3]

Per refinement: nodes, interface pairs, pairs closed by the preload, the tied
free-free frequencies of the first two elastic modes (bending along the bolt axis,
then across the width), the relative equilibrium error of the preload (sum of the
contact pressures against the three bolts' pretension), and the median wall
seconds of preparation (assembly and condensation), preload and tied modes over
``--repeats`` runs. Refine 3 needs about 3 GB and a minute per repeat; refine 4
about 6 GB (not run by default). A whole QSMA run is timed by the command line:
``qsma run --example brb --refine 2 --levels tip:log:1e-6:1e-3:13 --out DIR``.
"""
import argparse
import time

import numpy as np

from qsma.analysis import _Timer, prepare
from qsma.contact import OPEN
from qsma.examples.brb import brb
from qsma.options import RunOptions


def one(refine):
    """``(row of numbers, seconds per stage)`` of one tied analysis."""
    t0 = time.perf_counter()
    p = prepare(brb(refine))
    t1 = time.perf_counter()
    _, _, pre = p.preloaded(RunOptions(), _Timer())
    t2 = time.perf_counter()
    closed = pre.status != OPEN
    modes = p.mode(closed, RunOptions(n_modes=2), _Timer())[0]
    t3 = time.perf_counter()
    n0 = sum(b.pretension for b in p.model.bolts)
    row = dict(nodes=sum(b.mesh.n_nodes for b in p.model.bodies), pairs=p.pairing.n_pairs,
               closed=int(closed.sum()), f1=modes.f_hz[modes.n_rigid],
               f2=modes.f_hz[modes.n_rigid + 1],
               eq=abs(pre.lam[:, -1].sum() / n0 - 1))
    return row, (t1 - t0, t2 - t1, t3 - t2)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
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
