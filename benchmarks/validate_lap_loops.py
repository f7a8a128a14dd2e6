"""Convergence of the loop dissipation on the lap joint as the increments are refined.

For lap-2d (refine 1 and 2) at a few amplitudes, the stabilised-loop damping ratio with
the loop tolerance and branch increments refined together, and its error estimate.
Prints a table for docs/validation.md.

    python benchmarks/validate_lap_loops.py
"""
from __future__ import annotations

import argparse

import numpy as np

import qsma
from qsma.examples import lap_2d
from qsma.analysis.levels import Levels

SETTINGS = ((5e-3, 16), (5e-3, 32), (1e-3, 64))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--refine", type=int, nargs="+", default=[1, 2])
    p.add_argument("--tips", type=float, nargs="+", default=[5e-5, 1.2e-4, 2.5e-4, 1e-3])
    args = p.parse_args(argv)
    print("| refine | linear tip [m] | f [Hz] | " + " | ".join(
        f"zeta (rtol {r:g}, {s} steps)" for r, s in SETTINGS) + " | zeta Masing |")
    print("|---" * (4 + len(SETTINGS)) + "|")
    for refine in args.refine:
        levels = Levels("tip", tuple(args.tips))
        runs = [qsma.run(lap_2d(refine), levels=levels, dissipation="loop",
                         dissipation_rtol=r, loop_steps=s) for r, s in SETTINGS]
        for k, tip in enumerate(args.tips):
            cells = [f"{r.zeta[k]:.4e} +- "
                     f"{r.dissipation_error[k] / (2 * np.pi * r.alpha[k] * r.q[k]):.1e}"
                     if r.success else "failed" for r in runs]
            print(f"| {refine} | {tip:.2e} | {runs[-1].f_hz[k]:.2f} | " + " | ".join(cells)
                  + f" | {runs[-1].zeta_masing[k]:.4e} |", flush=True)


if __name__ == "__main__":
    main()
