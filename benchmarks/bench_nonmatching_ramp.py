"""Per-level cost of the load ramp: non-matching (mortar) against conforming interfaces
with the same number of contact points.

Usage: python benchmarks/bench_nonmatching_ramp.py [--refine 4] [--repeat 5]

Runs sandwich-2d (node-to-node) and the non-matching sandwich-2d of
``bench_nonmatching.py`` (top beam 48 x refine elements along the contact zone,
mortar, slave = the bottom beam: the same 65 x refine contact points) once, then
times the load ramp alone (the contact solves of all levels from the preload state,
open pairs eliminated, as ``qsma.run`` does) ``--repeat`` times, alternating the two
models, and prints the median milliseconds per level, the solver iterations summed
over the ramp and the seconds spent building the pairing (once per run).
"""
import argparse
import statistics
import time

import qsma
from qsma.analysis import _Solver, _ramp
from qsma.contact import ContactProblem
from qsma.contact.zone import zone_from_state
from qsma.examples import sandwich_2d

from bench_nonmatching import nonmatching_sandwich


def time_ramp(res):
    problem = ContactProblem(res.reduced.K, res.model.mu, dim=res.model.dim)
    solver = _Solver(problem, res.reduced, "basket", {},
                     zone_from_state(problem, res.preload.state))
    t0 = time.perf_counter()
    out = _ramp(solver, res.alpha, res.preload, False, None)
    return time.perf_counter() - t0, sum(out["nit"])


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--refine", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    runs = {"conforming": qsma.run(sandwich_2d(args.refine)),
            "non-matching": qsma.run(nonmatching_sandwich(args.refine, 48))}
    times = {k: [] for k in runs}
    for _ in range(args.repeat):
        for kind, res in runs.items():
            times[kind].append(time_ramp(res))
    print("| model | contact points | ms per level (median) | solver iterations | "
          "pairing s |")
    print("|---|---|---|---|---|")
    for kind, res in runs.items():
        ms = 1e3 * statistics.median(t for t, _ in times[kind]) / res.n_levels
        print(f"| {kind} | {res.model_info['n_pairs']} | {ms:.2f} | {times[kind][0][1]} | "
              f"{res.timings_s['model']:.3f} |")


if __name__ == "__main__":
    main()
