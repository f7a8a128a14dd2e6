"""The contact stage at scale: preload, load ramps, method choice (issue 14).

Usage: python benchmarks/bench_ramp.py [--cases sandwich-2d:1 sandwich-3d:1 lap-3d:2]
                                       [--methods basket active_set] [--repeat 3]
                                       [--preload-files F.npz ...] [--arithmetic]

Three tables.

1. Contact stage of a whole run, per case and method: each case is prepared once
   (assembly, condensation: ``qsma.analysis.prepare``), then ``run_prepared`` is timed
   ``--repeat`` times with a fresh cache; printed are the medians of the CPU time of
   the ``contact`` stage (preload, the refined +alpha ramp and the -alpha ramp, all
   threads), the number of contact solves, the time per solve, and the results of the
   last level (f0, q, zeta, stuck/slip/open), which must not change with the method
   or the code. ``--dissipation masing`` (default) skips the computed loops of the
   hysteresis stage (the lap joints' thousands of loop solves), which do not change
   the contact stage; on the sandwiches ``auto`` chooses Masing too.
2. The preload on the whole interface (``qsma.contact.solve``) against the preload on
   the predicted zone (``qsma.contact.zone.solve_preload``), on the cases' problems and
   on saved problems (``--preload-files``: npz with K, mu, gap0, dim, lam_w0): CPU
   medians measured in the same run, their ratio, the zone (predicted -> final pairs)
   and the largest differences of the two answers (relative to the largest value).
3. ``--arithmetic``: sandwich-2d refine 1, the 51-level ramp on the zone (what the run
   does) against its arithmetic: per level, the block steps' dense solves on the zone
   and the matrix-vector products of the checks, timed alone on matrices of the same
   sizes in the same run.

BLAS is limited to one thread (as qsma.run does at these sizes). Works on older
versions of qsma too (without ``solve_preload`` the zone column is left empty), so the
same command gives the before and after numbers.
"""
import argparse
from dataclasses import replace
import os
import statistics
import sys
import time
import warnings

import numpy as np
from threadpoolctl import threadpool_limits

from qsma import analysis
from qsma.analysis import prepare, run_prepared
from qsma.contact import ContactProblem, solve
from qsma.contact import zone as zone_module
from qsma.errors import ContactConvergenceWarning
from qsma.examples import EXAMPLES, sandwich_2d

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_scale import _instrumented_timer  # noqa: E402


def parse_case(text):
    name, _, refine = text.partition(":")
    return name, int(refine or 1)


def timed_run(prepared, method, dissipation):
    """One run from a fresh preparation cache: contact-stage CPU, solves, result."""
    record, calls, failed = {}, [0], [0]
    original_stage = _instrumented_timer(record)
    original_solve = analysis._solve

    def counting(*args, **kwargs):
        out = original_solve(*args, **kwargs)
        calls[0] += 1
        failed[0] += not out[0].success
        return out

    analysis._solve = counting
    try:
        res = run_prepared(replace(prepared, cache={}), method=method,
                           dissipation=dissipation)
    finally:
        analysis.StageClock.stage = original_stage
        analysis._solve = original_solve
    counts = [int(np.sum(res.states.status[-1] == s)) for s in (0, 1, 2)]
    return {"cpu": record["contact"]["cpu"], "solves": calls[0], "f0": res.f0_hz,
            "q": float(res.q[-1]), "zeta": float(res.zeta[-1]), "counts": counts,
            "failed": failed[0]}


def stage_table(cases, methods, repeat, dissipation):
    print("| case | pairs | method | contact stage CPU [s] | solves | per solve [ms] | "
          "/ basket | f0 [Hz] | q last | zeta last | stuck/slip/open | failed solves |")
    print("|---" * 12 + "|")
    problems = {}
    for name, refine in cases:
        prepared = prepare(EXAMPLES[name](refine))
        problems[f"{name} r{refine}"] = preload_problem(prepared)
        base = None
        for method in methods:
            runs = [timed_run(prepared, method, dissipation) for _ in range(repeat)]
            cpu = statistics.median(r["cpu"] for r in runs)
            r = runs[-1]
            base = cpu if base is None else base
            print(f"| {name} r{refine} | {problems[f'{name} r{refine}'][0].n_pairs} | "
                  f"{method} | {cpu:.3f} | {r['solves']} | {1e3 * cpu / r['solves']:.2f} | "
                  f"{cpu / base:.2f} | {r['f0']:.8f} | {r['q']:.10e} | {r['zeta']:.9e} | "
                  f"{'/'.join(map(str, r['counts']))} | {r['failed']} |",
                  flush=True)
    return problems


def preload_problem(prepared):
    """The contact problem and welded preload force of a prepared model."""
    problem = analysis._contact_problem(prepared.model, prepared.pairing, prepared.reduced.K)
    lam_w = prepared.reduced.welded_contact_force(analysis._load_factors(prepared.reduced, 0.0))
    return problem, lam_w


def load_problem(path):
    z = np.load(path)
    return ContactProblem(z["K"], z["mu"], z["gap0"], int(z["dim"])), z["lam_w0"]


def cpu_median(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        c0 = time.process_time()
        out = fn()
        times.append(time.process_time() - c0)
    return statistics.median(times), out


def preload_table(problems, repeat):
    print("\n| problem | pairs | unknowns | whole interface [s] | zone [s] | ratio | "
          "zone pairs (predicted -> final) | closed | same states | max diff d | "
          "max diff lam |")
    print("|---" * 11 + "|")
    zoned = getattr(zone_module, "solve_preload", None)
    for label, (problem, lam_w) in problems.items():
        t_full, full = cpu_median(lambda: solve(problem, lam_w), repeat)
        closed = int(np.sum(full.status != 2))
        if zoned is None:
            print(f"| {label} | {problem.n_pairs} | {problem.size} | {t_full:.3f} | - | - | "
                  f"- | {closed} | - | - | - |", flush=True)
            continue
        t_zone, (res, zone) = cpu_median(lambda: zoned(problem, lam_w), repeat)
        predicted = int(zone_module.predicted_zone(problem, lam_w).sum())
        same = bool(np.array_equal(res.status, full.status) and res.success and full.success)
        dd = np.abs(res.d - full.d).max() / np.abs(full.d).max()
        dl = np.abs(res.lam - full.lam).max() / np.abs(full.lam).max()
        print(f"| {label} | {problem.n_pairs} | {problem.size} | {t_full:.3f} | {t_zone:.3f} | "
              f"{t_full / t_zone:.1f} | {predicted} -> {int(zone.keep.sum())} | {closed} | "
              f"{same} | {dd:.1e} | {dl:.1e} |", flush=True)


def arithmetic_table(repeat):
    """sandwich-2d refine 1: per-level time of the zone ramp against its kernels."""
    res = analysis.run(sandwich_2d(1))
    problem = ContactProblem(res.reduced.K, res.model_info["mu"])
    loads = [res.reduced.welded_contact_force([1.0, a]) for a in res.alpha]
    state0 = res.preload.state
    zone0 = zone_module.zone_from_state(problem, state0)

    def ramp():
        z, state, steps, unknowns = zone0, state0, [], []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ContactConvergenceWarning)
            for lw in loads:
                r, z = zone_module.solve_in_zone(z, lw, state)
                state = r.state
                steps.append(r.nit)
                sub = r.status[z.keep]
                unknowns.append(int(np.sum(sub == 2) * problem.dim + np.sum(sub == 1)
                                    * (problem.dim - 1)))
        return steps, unknowns, z

    t_ramp, (steps, unknowns, z) = cpu_median(ramp, repeat)
    n_zone, n_full = z.sub.size, problem.size
    rng = np.random.default_rng(0)

    def kernel_time(fn):
        return cpu_median(lambda: [fn() for _ in range(200)], repeat)[0] / 200

    t_mv_zone = kernel_time(lambda: z.sub.K @ rng.random(n_zone))
    t_check = kernel_time(lambda: (problem.K @ rng.random(n_full),
                                   problem.abs_K @ rng.random(n_full)))
    floor, flops = 0.0, 0.0
    for nit, nu in zip(steps, unknowns):
        A = z.sub.K[:nu, :nu]
        t_solve = kernel_time(lambda: np.linalg.solve(A, rng.random(nu))) if nu else 0.0
        floor += max(nit, 1) * (t_solve + t_mv_zone) + t_check
        flops += max(nit, 1) * (2 / 3 * nu ** 3 + 2 * n_zone ** 2) + 4 * n_full ** 2
    per_level = t_ramp / len(loads)
    print(f"\nsandwich-2d refine 1: {len(loads)} levels, zone {n_zone} of {n_full} unknowns, "
          f"{sum(steps)} block steps; ramp {1e3 * t_ramp:.1f} ms CPU, "
          f"{1e3 * per_level:.3f} ms per level; arithmetic {flops / len(loads):.3g} flop "
          f"per level, its kernels alone {1e3 * floor / len(loads):.4f} ms per level; "
          f"ratio {t_ramp / floor:.0f}x")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", default=["sandwich-2d:1", "sandwich-3d:1", "lap-3d:2"])
    ap.add_argument("--methods", nargs="+", default=["basket", "active_set"])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--preload-files", nargs="*", default=[])
    ap.add_argument("--arithmetic", action="store_true")
    ap.add_argument("--dissipation", default="masing",
                    help="RunOptions.dissipation (default masing: no loops, which are the "
                         "hysteresis stage, not the contact stage)")
    args = ap.parse_args()
    with threadpool_limits(1, "blas"):
        problems = {}
        if args.cases:
            problems = stage_table([parse_case(c) for c in args.cases], args.methods,
                                   args.repeat, args.dissipation)
        for path in args.preload_files:
            problems[os.path.basename(path)] = load_problem(path)
        if problems:
            preload_table(problems, args.repeat)
        if args.arithmetic:
            arithmetic_table(args.repeat)


if __name__ == "__main__":
    main()
