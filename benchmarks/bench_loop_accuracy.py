"""Computed loops of a default run against converged references, with their cost.

For each case: the default run with a loop at every level (``dissipation="loop"``, every
other option at its default); at the chosen levels, a reference run at those amplitudes
only with every refinement tightened (``dissipation_rtol`` 2e-4, so a denser backbone
and tighter loops; ``loop_steps`` 64; ``max_cycles`` 40; five loop refinement rounds).
Per level: the default's dissipation and its reported error estimate, the
reference's, and the distance between them in units of the default's estimate (at
most 1: the estimate is honest); then the loops' solves and seconds in the default run.

    python benchmarks/bench_loop_accuracy.py --cases lap-3d:1 brb:1 \
        --levels 16 19 22 25 30 35 40 45 47 50
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import qsma
from qsma.hysteresis import refinement as hysteresis
from qsma.examples import EXAMPLES
from qsma.analysis.levels import Levels

#: The reference's settings (its loop refinement rounds: hysteresis.REFINE_ROUNDS).
REFERENCE = dict(dissipation_rtol=2e-4, loop_steps=64, max_cycles=40)
REFERENCE_ROUNDS = 5


def reference(model, alphas):
    """The loops at ``alphas`` with every refinement tightened (:data:`REFERENCE`)."""
    rounds = hysteresis.REFINE_ROUNDS
    hysteresis.REFINE_ROUNDS = REFERENCE_ROUNDS
    try:
        return qsma.run(model, levels=Levels("alpha", tuple(alphas)), dissipation="loop",
                        **REFERENCE)
    finally:
        hysteresis.REFINE_ROUNDS = rounds


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="+", default=["lap-3d:1", "brb:1"], help="EXAMPLE:REFINE")
    p.add_argument("--levels", type=int, nargs="+",
                   default=[16, 19, 22, 25, 30, 35, 40, 45, 47, 50],
                   help="levels of the default grid compared")
    args = p.parse_args(argv)
    print("| case | level | A | D (default) | estimate | D (reference) | its estimate | "
          "\\|D - D_ref\\| / estimate | \\|D - D_ref\\| / D_ref | loop solves | loop [s] |")
    print("|---" * 11 + "|")
    for case in args.cases:
        name, refine = case.split(":")
        model = EXAMPLES[name](int(refine))
        t = time.perf_counter()
        run = qsma.run(model, dissipation="loop")
        wall = time.perf_counter() - t
        levels = [k for k in args.levels if k < run.n_levels]
        ref = reference(model, run.alpha[levels])
        costs = run.level_costs
        for j, k in enumerate(levels):
            D, est, R = run.dissipation[k], run.dissipation_error[k], ref.dissipation[j]
            relative = f"{abs(D - R) / abs(R):.1e}" if R != 0 else "- (D_ref = 0)"
            print(f"| {case} | {k} | {run.alpha[k]:.4g} | {D:.5e} | {est:.1e} | {R:.5e} | "
                  f"{ref.dissipation_error[j]:.1e} | {abs(D - R) / est:.2f} | "
                  f"{relative} | {costs.loop_solves[k]} | "
                  f"{costs.loop_seconds[k]:.2f} |", flush=True)
        print(f"\n{case}: default run {wall:.1f} s wall, hysteresis "
              f"{run.timings_s['hysteresis']:.1f} s, {int(np.sum(costs.loop_solves))} loop "
              f"solves, {int(np.sum(costs.loop_cycles))} cycles, success {run.success}\n",
              flush=True)


if __name__ == "__main__":
    main()
