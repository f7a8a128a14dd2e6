"""Where one contact solve of a run goes: the zone solves of a whole run, replayed.

Usage: python benchmarks/bench_contact_overhead.py [--cases sandwich-2d:1 sandwich-3d:1]
                                                   [--repeat 3]
       python benchmarks/bench_contact_overhead.py --block-steps [--cases lap-3d:2]
                                                   [--levels tip:log:1e-4:1e-3:2]
                                                   [--max-systems 1500] [--repeat 3]

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

``--block-steps``: the block steps of a run with computed loops (``dissipation="loop"``
at ``--levels``), replayed. Each :class:`qsma.contact.linear.BlockSystem` of the run (up
to ``--max-systems``) is recorded with the slip directions of its steps; the replay
solves every step twice per repeat, alternating: directly (the step's matrix formed and
``numpy.linalg.solve``, what every step did before the factors were reused) and with
``BlockSystem.solve`` (refinement with the kept factors where it converges). Printed:
the median CPU ms per step of each, their ratio, the factorisations, refined steps and
corrections, and the largest difference of the two answers (relative to the largest
value of the step). Needs the version of ``qsma.contact.linear`` with the reused
factors; the run itself may be recorded with any.

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

import qsma
import qsma.analysis as analysis
from qsma.analysis import prepare, run_prepared
from qsma.contact import basket, linear, zone as zone_module
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

    analysis.solves.solve_in_zone = recording
    try:
        run_prepared(prepared, dissipation="masing")
    finally:
        analysis.solves.solve_in_zone = original
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


def recorded_block_steps(case, levels, max_systems):
    """The block systems of one run of ``case`` with loops at ``levels``: per system its
    inputs and the ``(direction, alpha, c)`` of each step, directions of all pairs."""
    from qsma.cli.run import parse_levels_spec
    name, _, refine = case.partition(":")
    records, cls = [], linear.BlockSystem
    original_init, original_solve = cls.__init__, cls.solve

    def init(self, problem, lam_w, status, d_prev):
        original_init(self, problem, lam_w, status, d_prev)
        self._record = None
        if len(records) < max_systems and self.unknown.size:
            self._record = (problem, np.array(lam_w), np.array(status), np.array(d_prev), [])
            records.append(self._record)

    def solve(self, direction, alpha, c):
        if self._record is not None:
            self._record[4].append((np.array(direction), np.array(alpha), c))
        return original_solve(self, direction, alpha, c)

    cls.__init__, cls.solve = init, solve
    try:
        qsma.run(EXAMPLES[name](int(refine or 1)), levels=parse_levels_spec(levels),
                 dissipation="loop")
    finally:
        cls.__init__, cls.solve = original_init, original_solve
    return records


def direct_step(system, direction, alpha, c):
    """The step as before the reused factors: its matrix formed, ``numpy.linalg.solve``."""
    d = system.d_known.copy()
    rows, rhs = linear._slip_law_rows(system.K_t, system.K_n, system.f_t, system.f_n,
                                      system.mu, direction[system.slip], alpha[system.slip],
                                      system.t_prev, c, system.at)
    A = np.concatenate([system.K_open, rows.reshape(-1, system.unknown.size)])
    d[system.unknown] = np.linalg.solve(A, np.concatenate([-system.f_open, rhs.ravel()]))
    return d


def replay_steps(records, direct):
    """CPU seconds of the steps (systems built outside the timer), the answers and the
    counts ``(factorisations, refined, corrections)``."""
    spent, answers, counts = 0.0, [], np.zeros(3, int)
    for problem, lam_w, status, d_prev, steps in records:
        system = linear.BlockSystem(problem, lam_w, status, d_prev)
        start = time.process_time()
        for direction, alpha, c in steps:
            answers.append(direct_step(system, direction, alpha, c) if direct
                           else system.solve(direction, alpha, c))
        spent += time.process_time() - start
        if not direct:
            counts += (system.n_factorised, system.n_refined, system.n_corrections)
    return spent, answers, counts


def block_steps(args):
    print("| case | systems | steps | unknowns median / max | direct, ms per step | "
          "reused factors, ms per step | ratio | factorisations / refined / corrections | "
          "max diff |")
    print("|---|---|---|---|---|---|---|---|---|")
    for case in args.cases:
        records = recorded_block_steps(case, args.levels, args.max_systems)
        steps = sum(len(r[4]) for r in records)
        sizes = [linear.BlockSystem(*r[:4]).unknown.size for r in records]
        times = {True: [], False: []}
        for _ in range(args.repeat):
            for direct in (True, False):
                spent, answers, counts = replay_steps(records, direct)
                times[direct].append(spent)
                if direct:
                    reference = answers
        worst = max(float(np.abs(a - b).max() / max(np.abs(b).max(), np.finfo(float).tiny))
                    for a, b in zip(answers, reference))
        old, new = (1e3 * statistics.median(times[k]) / steps for k in (True, False))
        print(f"| {case} | {len(records)} | {steps} | {int(np.median(sizes))} / {max(sizes)} "
              f"| {old:.3f} | {new:.3f} | {new / old:.2f} | "
              f"{' / '.join(str(int(c)) for c in counts)} | {worst:.1e} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--block-steps", action="store_true")
    ap.add_argument("--levels", default="tip:log:1e-4:1e-3:2")
    ap.add_argument("--max-systems", type=int, default=1500)
    args = ap.parse_args()
    warnings.simplefilter("ignore", ContactConvergenceWarning)
    if args.block_steps:
        args.cases = args.cases or ["lap-3d:2"]
        with threadpool_limits(1):
            block_steps(args)
        return
    args.cases = args.cases or ["sandwich-2d:1", "sandwich-3d:1"]
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
