"""Where one contact solve of a run goes: the zone solves of a whole run, replayed.

Usage: python benchmarks/bench_contact_overhead.py [--cases sandwich-2d:1 sandwich-3d:1]
                                                   [--repeat 3]

Each case is prepared and run once (``dissipation="masing"``) with
``qsma.contact.zone.solve_in_zone`` recorded: its inputs (zone, load, previous state,
options, guess) and its answer. The recorded calls are then replayed ``--repeat``
times with the same code, BLAS on one thread, and the table gives the median CPU time
per solve, the block steps (``nit``) of all solves, how many guesses were accepted
without iterating, and the largest difference of the replayed answers from the
recorded ones (zero: the replay is the run's arithmetic). A second table splits the
median wall time of a solve into its parts (timers around the zone iteration, the
basket inside it, the expansion to all pairs, the full problem's check and the
result), measured in one extra replay.

Works on older versions of qsma too, so the same command gives before and after
numbers (``PYTHONPATH=<old>/src``).
"""
import argparse
import collections
import statistics
import time
import warnings

import numpy as np
from threadpoolctl import threadpool_limits

import qsma.analysis as analysis
from qsma.analysis import prepare, run_prepared
from qsma.contact import basket, zone as zone_module
from qsma.errors import ContactConvergenceWarning
from qsma.examples import EXAMPLES

PARTS = (("zone iteration (solve on the zone)", zone_module, "solve"),
         ("  of which the basket", basket, "run_baskets"),
         ("expansion to all pairs", zone_module.ContactZone, "expand"),
         ("full problem's check", zone_module, "measures"),
         ("result (classification)", zone_module, "_result"))


def recorded_calls(case):
    """The ``solve_in_zone`` calls of one run of ``case`` (name:refine)."""
    name, _, refine = case.partition(":")
    prepared = prepare(EXAMPLES[name](int(refine or 1)))
    calls, original = [], zone_module.solve_in_zone

    def recording(zone, lam_w, state, **options):
        res, grown = original(zone, lam_w, state, **options)
        calls.append((zone, np.array(lam_w), state, options, res))
        return res, grown

    analysis.solve_in_zone = recording
    try:
        run_prepared(prepared, dissipation="masing")
    finally:
        analysis.solve_in_zone = original
    return calls


def replay(calls):
    """One replay: CPU seconds, block steps, accepted guesses, largest difference."""
    nit, held, worst = 0, 0, 0.0
    start = time.process_time()
    for zone, lam_w, state, options, old in calls:
        res, _ = zone_module.solve_in_zone(zone, lam_w, state, **options)
        nit += res.nit
        held += options.get("guess") is not None and res.nit == 0
        scale = max(np.abs(old.d).max(), np.finfo(float).tiny)
        worst = max(worst, float(np.abs(res.d - old.d).max() / scale))
    return time.process_time() - start, nit, held, worst


def split(calls):
    """Wall time per solve of each part of :data:`PARTS` over one replay."""
    spent, originals = collections.defaultdict(float), []
    for label, owner, name in PARTS:
        fn = getattr(owner, name)
        originals.append((owner, name, fn))

        def timed(*args, _fn=fn, _label=label, **kw):
            t = time.perf_counter()
            try:
                return _fn(*args, **kw)
            finally:
                spent[_label] += time.perf_counter() - t
        setattr(owner, name, timed)
    try:
        t = time.perf_counter()
        for zone, lam_w, state, options, _ in calls:
            zone_module.solve_in_zone(zone, lam_w, state, **options)
        total = time.perf_counter() - t
    finally:
        for owner, name, fn in originals:
            setattr(owner, name, fn)
    n = len(calls)
    return 1e3 * total / n, {label: 1e3 * spent[label] / n for label, _, _ in PARTS}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["sandwich-2d:1", "sandwich-3d:1"])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    warnings.simplefilter("ignore", ContactConvergenceWarning)
    rows, parts = [], []
    with threadpool_limits(1):
        for case in args.cases:
            calls = recorded_calls(case)
            runs = [replay(calls) for _ in range(args.repeat)]
            cpu = statistics.median(r[0] for r in runs)
            _, nit, held, worst = runs[-1]
            guessed = sum(c[3].get("guess") is not None for c in calls)
            rows.append(f"| {case} | {len(calls)} | {1e3 * cpu / len(calls):.2f} | "
                        f"{' / '.join(f'{1e3 * r[0] / len(calls):.2f}' for r in runs)} | "
                        f"{nit} | {held} of {guessed} | {worst:.1e} |")
            total, by_part = split(calls)
            parts.append((case, total, by_part))
    print("| case | solves | CPU per solve, median [ms] | runs [ms] | block steps | "
          "guesses accepted | max diff d |")
    print("|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    print()
    print("| part (wall ms per solve) | " + " | ".join(c for c, _, _ in parts) + " |")
    print("|---|" + "---|" * len(parts))
    for label, _, _ in PARTS:
        print(f"| {label} | " + " | ".join(f"{p[label]:.2f}" for _, _, p in parts) + " |")
    print("| whole solve | " + " | ".join(f"{t:.2f}" for _, t, _ in parts) + " |")


if __name__ == "__main__":
    main()
