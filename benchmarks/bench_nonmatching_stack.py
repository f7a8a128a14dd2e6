"""stack-2d (three plates, two interfaces): matching against non-matching middle plate.

    python benchmarks/bench_nonmatching_stack.py [--refine 1 2] [--levels 11]

Per refinement, two runs of ``qsma.run`` on tip levels log-spaced 1e-6 .. 1e-4 m:
the middle plate meshed like the outer ones (both interfaces node-to-node) and
with 48 instead of 64 elements along the contact zone (both mortar). Prints f0,
zeta at three levels, the contact points and the seconds of each run (one run
each: this is an accuracy table, not a timing study).
"""
from __future__ import annotations

import argparse
import time

import qsma
from qsma.examples import STACK_2D, stack_2d


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, nargs="+", default=[1])
    ap.add_argument("--levels", type=int, default=11)
    args = ap.parse_args(argv)
    levels = qsma.Levels.log("tip", 1e-6, 1e-4, args.levels)
    picks = [args.levels // 2, (3 * args.levels) // 4, args.levels - 1]
    head = " | ".join(f"zeta[{k}]" for k in picks)
    print(f"| refine | middle | coupling | pairs | f0 [Hz] | {head} | s |")
    print("|---" * (6 + len(picks)) + "|")
    for refine in args.refine:
        for label, n_mid in (("matching", STACK_2D["n_fine"]),
                             ("non-matching", STACK_2D["n_fine_middle"])):
            t0 = time.perf_counter()
            res = qsma.run(stack_2d(refine, n_fine_middle=n_mid), levels=levels)
            dt = time.perf_counter() - t0
            if not res.success:
                print(f"| {refine} | {label} | failed: {res.message} |")
                continue
            zetas = " | ".join(f"{res.zeta[k]:.4e}" for k in picks)
            print(f"| {refine} | {label} | {res.pairing.coupling} | {res.pairing.n_pairs} | "
                  f"{res.f0_hz:.4f} | {zetas} | {dt:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
