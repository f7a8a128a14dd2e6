"""Contact methods on the sandwich-2d load ramp (51 levels), per refinement.

Usage: python benchmarks/bench_contact_sandwich.py [--refine 1 2 4 8] [--repeat 3]
                                                   [--nodal-maxiter 100]

For each refinement the reduced problem, the preload state and the 51 welded
forces come from one ``qsma.run``; then every method solves the same ramp,
warm-started level to level, on (a) the full interface problem and (b) the
contact zone with the open pairs eliminated exactly (qsma.contact.zone, what
``qsma.run`` does). Printed: median ramp time over ``--repeat`` runs, time per
level, total iterations, failed levels, largest residual, and the time relative
to ``basket`` on the same problem in the same run. BLAS runs single-threaded
(as qsma.run does for these sizes).
"""
import argparse
import statistics
import time
import warnings

from threadpoolctl import threadpool_limits

import qsma
from qsma.contact import ContactProblem, solve
from qsma.contact.zone import solve_in_zone, zone_from_state
from qsma.errors import ContactConvergenceWarning
from qsma.examples import sandwich_2d


def ramp_inputs(refine):
    res = qsma.run(sandwich_2d(refine))
    problem = ContactProblem(res.reduced.K, res.model_info["mu"])
    loads = [res.reduced.welded_contact_force([1.0, a]) for a in res.alpha]
    return problem, res.preload.state, loads


def run(problem, state, loads, method, zone, maxiter):
    z = zone_from_state(problem, state) if zone else None
    nit, failed, worst = 0, 0, 0.0
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        for lw in loads:
            if zone:
                r, z = solve_in_zone(z, lw, state, method=method, maxiter=maxiter)
            else:
                r = solve(problem, lw, state, method=method, maxiter=maxiter)
            nit += r.nit
            failed += not r.success
            worst = max(worst, r.residual)
            state = r.state
    return time.perf_counter() - t, nit, failed, worst


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--nodal-maxiter", type=int, default=100)
    args = ap.parse_args()
    print("| refine | pairs | problem | method | ramp [ms] | per level [ms] | iterations "
          "| failed levels | max residual | / basket |")
    print("|---" * 10 + "|")
    with threadpool_limits(1, "blas"):
        for r in args.refine:
            problem, state, loads = ramp_inputs(r)
            for zone in (False, True):
                methods = ["basket", "active_set", "nodal_gs"]
                base = None
                for m in methods:
                    maxiter = args.nodal_maxiter if m == "nodal_gs" else None
                    reps = 1 if m == "nodal_gs" else args.repeat
                    runs = [run(problem, state, loads, m, zone, maxiter) for _ in range(reps)]
                    t = statistics.median(x[0] for x in runs)
                    _, nit, failed, worst = runs[-1]
                    base = t if m == "basket" else base
                    print(f"| {r} | {problem.n_pairs} | {'zone' if zone else 'full'} | {m} | "
                          f"{1e3 * t:.1f} | {1e3 * t / len(loads):.2f} | {nit} | {failed} | "
                          f"{worst:.1e} | {t / base:.2f} |", flush=True)


if __name__ == "__main__":
    main()
