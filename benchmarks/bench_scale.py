"""How each stage of a QSMA run grows with the model: sandwich-3d at several refinements.

Usage: python benchmarks/bench_scale.py [--refine 1 2] [--repeat 3 1] [--json out.json]
                                        [--method basket] [--schur-backend auto] [--quick]
       python benchmarks/bench_scale.py --tables r1.json r2.json   (reprint saved rows)

Per refinement, ``qsma.run`` is called ``--repeat`` times (one number per refinement,
the last one repeated) and every stage of results.json ``timings_s`` is measured four
ways: wall time, CPU time of the process and of the child processes it waited for
(all threads; more than the wall time where
BLAS runs on both cores, and the honest measure on a shared machine where the wall time
waits for other jobs), the CPU time of the process alone (what the forked children,
the -alpha ramp and the tied modes beyond the loaded one, take off the run's own path
where a second core is free), and the peak resident memory during the stage (Linux ``VmHWM``,
reset at the start of each stage; qsma._infra.resources), and the resident memory left at
the end of each stage, beside the MB of the dense interface matrices the result holds
and the number of K_EE factorisations (congruent bodies share one, qsma.reduction.congruence).
The table gives the medians over
the repeats and the process peak. The last table fits ``cost ~ n^p`` by least squares
in log-log over the refinements, once against the number of DOFs and once against the
number of interface pairs, so that a larger model can be predicted. The results f0, q
and zeta of the last level are printed so that a change of method can be checked
against them (``--json`` writes them with all the numbers). ``--quick`` runs two load
levels (tip 1e-7 and 2e-7, not refined) instead of the default ramp: the assembly,
the condensation and the tied modes are the same, the contact stage is short, and
the results of the last level are those of 2e-7 (f0 is comparable, q and zeta not).
"""
import argparse
from contextlib import contextmanager
import json
import os
import statistics

import numpy as np

import qsma
from qsma._infra import resources as _resources
from qsma import analysis
from qsma.analysis import STAGES
from qsma.examples import sandwich_3d

MEASURED = [s for s in STAGES if s != "total"]


def _instrumented_timer(record):
    """Wrap ``analysis.StageClock.stage`` so each stage also records CPU and peak memory."""
    original = analysis.StageClock.stage

    @contextmanager
    def stage(self, name):
        _resources.reset_peak()
        c0, own0 = _resources.cpu_with_children_s(), _own_cpu_s()
        with original(self, name):
            yield
        cpu = _resources.cpu_with_children_s() - c0
        entry = record.setdefault(name, {"cpu": 0.0, "own": 0.0, "peak_mb": 0.0})
        entry["cpu"] += cpu
        entry["own"] += _own_cpu_s() - own0
        entry["peak_mb"] = max(entry["peak_mb"], _resources.peak_memory_mb() or 0.0)
        entry["held_mb"] = _resources.current_memory_mb() or 0.0   # at its last end

    analysis.StageClock.stage = stage
    return original


def _own_cpu_s():
    """CPU seconds of this process alone (all its threads, not its children)."""
    t = os.times()
    return t.user + t.system


def measure(refine, options):
    """One run: wall/CPU/peak per stage, model size and the checked results."""
    record = {}
    original = _instrumented_timer(record)
    c0 = _resources.cpu_with_children_s()
    try:
        res = qsma.run(sandwich_3d(refine), **options)
    finally:
        analysis.StageClock.stage = original
    info = res.model_info
    return {
        "refine": refine, "n_dofs": info["n_dofs"], "n_pairs": info["n_pairs"],
        "success": bool(res.success),
        "wall": {k: res.timings_s[k] for k in STAGES},
        "own": {k: record.get(k, {}).get("own", 0.0) for k in MEASURED},
        "cpu": {**{k: record.get(k, {}).get("cpu", 0.0) for k in MEASURED},
                "total": _resources.cpu_with_children_s() - c0},
        "peak_mb": {k: record.get(k, {}).get("peak_mb", 0.0) for k in MEASURED},
        "held_mb": {k: record.get(k, {}).get("held_mb", 0.0) for k in MEASURED},
        "interface_mb": _interface_mb(res.reduced),
        "factors": _factors(res.reduced),
        "process_peak_mb": max([_resources.peak_memory_mb() or 0.0]
                               + [v["peak_mb"] for v in record.values()]),
        "child_peak_mb": _resources.children_peak_memory_mb() or 0.0,
        "f0_hz": res.f0_hz, "q_last": float(res.q[-1]), "zeta_last": float(res.zeta[-1]),
        "counts_last": [int(np.sum(res.states.status[-1] == s)) for s in (0, 1, 2)],
    }


def _interface_mb(reduced):
    """MB of the dense interface matrices the result's reduced model holds: each
    body's Kc, the factor of S, K and W (base model of locked bolts)."""
    rm = getattr(reduced, "base", reduced)
    arrays = [b.Kc for b in rm.bodies] + [rm.S_cho[0], rm.K, rm.W]
    return sum(a.nbytes for a in arrays) / 2**20


def _factors(reduced):
    """Number of distinct K_EE factorisations the bodies use (congruent bodies share
    one, qsma.reduction.congruence)."""
    rm = getattr(reduced, "base", reduced)
    return len({id(getattr(b.solve_EE, "base", b.solve_EE)) for b in rm.bodies})


def median_run(runs):
    med = dict(runs[-1])
    for key in ("wall", "cpu", "own", "peak_mb", "held_mb"):
        if key in runs[0]:
            med[key] = {k: statistics.median(r[key][k] for r in runs) for k in runs[0][key]}
    med["runs"] = len(runs)
    return med


def fitted_exponent(sizes, costs):
    """Least-squares slope of log(cost) against log(size); NaN with < 2 sizes."""
    sizes, costs = np.asarray(sizes, float), np.asarray(costs, float)
    ok = costs > 0
    if np.unique(sizes[ok]).size < 2:
        return float("nan")
    return float(np.polyfit(np.log(sizes[ok]), np.log(costs[ok]), 1)[0])


def print_tables(rows):
    print("\n| refine | DOFs | pairs | runs | " + " | ".join(STAGES) + " | peak memory [MB] |")
    print("|---" * (len(STAGES) + 5) + "|")
    for r in rows:
        cells = [f"{r['wall'][k]:.2f} / {r['cpu'][k]:.2f}" for k in STAGES]
        print(f"| {r['refine']} | {r['n_dofs']} | {r['n_pairs']} | {r['runs']} | "
              + " | ".join(cells) + f" | {r['process_peak_mb']:.0f} |")
    if all("own" in r for r in rows):
        print("\nCPU of the run's own process per stage [s] (its forked children apart: "
              "what a free second core takes off the run's path):\n")
        print("| refine | " + " | ".join(MEASURED) + " |")
        print("|---" * (len(MEASURED) + 1) + "|")
        for r in rows:
            print(f"| {r['refine']} | " + " | ".join(f"{r['own'][k]:.2f}" for k in MEASURED)
                  + " |")
    print("\nStage peak resident memory [MB]:\n")
    print("| refine | " + " | ".join(MEASURED) + " |")
    print("|---" * (len(MEASURED) + 1) + "|")
    for r in rows:
        print(f"| {r['refine']} | " + " | ".join(f"{r['peak_mb'][k]:.0f}" for k in MEASURED)
              + " |")
    print("\nResident memory at the end of each stage [MB] (what it leaves held):\n")
    print("| refine | " + " | ".join(MEASURED) + " | dense interface matrices | "
          "K_EE factors |")
    print("|---" * (len(MEASURED) + 3) + "|")
    for r in rows:
        if "held_mb" in r:
            print(f"| {r['refine']} | " + " | ".join(f"{r['held_mb'][k]:.0f}" for k in MEASURED)
                  + f" | {r['interface_mb']:.0f} | {r['factors']} |")
    print("\nFitted exponents p of CPU time ~ n^p (n = DOFs | interface pairs):\n")
    print("| stage | p (DOFs) | p (pairs) |")
    print("|---|---|---|")
    for k in MEASURED + ["total"]:
        costs = [r["cpu"][k] for r in rows]
        print(f"| {k} | {fitted_exponent([r['n_dofs'] for r in rows], costs):.2f} | "
              f"{fitted_exponent([r['n_pairs'] for r in rows], costs):.2f} |")
    print("\nResults (last level): \n")
    for r in rows:
        print(f"refine {r['refine']}: success {r['success']}, f0 = {r['f0_hz']!r} Hz, "
              f"q = {r['q_last']!r}, zeta = {r['zeta_last']!r}, "
              f"stuck/slip/open = {r['counts_last']}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeat", type=int, nargs="+", default=[3, 1])
    ap.add_argument("--method", default=None, help="contact method (default: qsma's)")
    ap.add_argument("--schur-backend", default=None)
    ap.add_argument("--json", default=None, help="also write every number to this file")
    ap.add_argument("--serial-ramps", action="store_true",
                    help="RunOptions(parallel_ramps=False): the -alpha ramp after the +alpha "
                         "one in this process")
    ap.add_argument("--quick", action="store_true",
                    help="two load levels, not refined (no long ramp)")
    ap.add_argument("--tables", nargs="+", default=None,
                    help="print the tables of rows saved by --json (runs done separately, "
                         "e.g. the large refinement alone in the background)")
    args = ap.parse_args()
    if args.tables:
        rows = []
        for path in args.tables:
            with open(path) as f:
                rows += json.load(f)
        print_tables(sorted(rows, key=lambda r: r["n_dofs"]))
        return
    options = {k: v for k, v in (("method", args.method),
                                 ("schur_backend", args.schur_backend)) if v is not None}
    if args.serial_ramps:
        options["parallel_ramps"] = False
    if args.quick:
        options.update(levels=qsma.Levels.log("tip", 1e-7, 2e-7, 2), refine_levels=False)
    print("sandwich-3d; per stage: wall s / CPU s (median of the runs)", flush=True)
    rows = []
    for i, refine in enumerate(args.refine):
        n = args.repeat[min(i, len(args.repeat) - 1)]
        runs = []
        for _ in range(n):
            runs.append(measure(refine, options))
            r = runs[-1]
            print(f"refine {refine}: wall {r['wall']['total']:.1f} s, CPU "
                  f"{r['cpu']['total']:.1f} s, peak {r['process_peak_mb']:.0f} MB "
                  f"(a child process: {r['child_peak_mb']:.0f} MB)", flush=True)
        rows.append(median_run(runs))
    print_tables(rows)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
