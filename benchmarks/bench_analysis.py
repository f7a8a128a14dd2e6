"""Time the whole QSMA of sandwich-2d per stage (median of several runs).

Usage: python benchmarks/bench_analysis.py [--example sandwich-2d|sandwich-3d]
                                          [--refine 1 2 4 8] [--repeat 5] [--method basket]

Stages are those of results.json ``timings_s`` (model to results, excluding
interpreter start-up, plots and file writing). The last columns compare the
contact ramp and the whole analysis with the published reference (4 s of Matlab
for the 51-level contact ramp; 201 s of a commercial FE code for the 51 levels).
"""
import argparse
import statistics

import qsma
from qsma.analysis import STAGES
from qsma.examples import EXAMPLES

MATLAB_RAMP_S, COMMERCIAL_S = 4.0, 201.0


def measure(example, refine, repeat, method):
    runs = []
    for _ in range(repeat):
        res = qsma.run(EXAMPLES[example](refine), method=method)
        assert res.success, res.message
        runs.append(res.timings_s)
    med = {k: statistics.median(r[k] for r in runs) for k in STAGES}
    return med, res


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--method", default="basket")
    ap.add_argument("--example", default="sandwich-2d", choices=sorted(EXAMPLES))
    args = ap.parse_args()
    print(f"{args.example}, method {args.method}, median of {args.repeat} runs, seconds")
    ref = "" if args.example == "sandwich-2d" else " (2D references)"
    print("| refine | nodes | pairs | " + " | ".join(STAGES)
          + f" | ramp vs Matlab 4 s{ref} | total vs FE 201 s{ref} |")
    print("|---" * (len(STAGES) + 5) + "|")
    for r in args.refine:
        med, res = measure(args.example, r, args.repeat, args.method)
        info = res.model_info
        print(f"| {r} | {info['n_nodes']} | {info['n_pairs']} | "
              + " | ".join(f"{med[k]:.4f}" for k in STAGES)
              + f" | {MATLAB_RAMP_S / med['contact']:.0f}x | {COMMERCIAL_S / med['total']:.0f}x |",
              flush=True)


if __name__ == "__main__":
    main()
