"""Cost of the hysteresis stage: Masing only, auto, and loops at every level.

For each model and dissipation mode, the median over ``--repeat`` runs of the
``contact`` stage (the +alpha and -alpha ramps, refined levels included), the
``hysteresis`` stage (the computed loops) and the whole analysis, with the ratio of
(contact + hysteresis) to the contact stage of the Masing-only run on the user's
51 levels (``dissipation="masing", refine_levels=False``, the pre-0.2 analysis).

    python benchmarks/bench_hysteresis.py --repeat 3
"""
from __future__ import annotations

import argparse
import statistics

import qsma
from qsma.examples import EXAMPLES

CASES = (("Masing, 51 levels (old)", dict(dissipation="masing", refine_levels=False)),
         ("Masing, refined levels", dict(dissipation="masing")),
         ("auto (default)", dict()),
         ("loops at every level", dict(dissipation="loop")))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--examples", nargs="+", default=["sandwich-2d", "lap-2d"])
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    print("| model | dissipation | backbone points | loop solves | contact [s] | "
          "hysteresis [s] | total [s] | (contact+hysteresis) / old contact |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.examples:
        base = None
        for label, opts in CASES:
            runs = [qsma.run(EXAMPLES[name](1), **opts) for _ in range(args.repeat)]
            med = {k: statistics.median(r.timings_s[k] for r in runs)
                   for k in ("contact", "hysteresis", "total")}
            base = med["contact"] if base is None else base
            r = runs[0]
            print(f"| {name} | {label} | {r.solver['backbone_points']} | "
                  f"{r.solver['loop_solves']} | {med['contact']:.3f} | "
                  f"{med['hysteresis']:.3f} | {med['total']:.3f} | "
                  f"{(med['contact'] + med['hysteresis']) / base:.1f}x |", flush=True)


if __name__ == "__main__":
    main()
