"""The contact solves of computed loops, one by one: CPU per solve of ``active_set`` as it
runs, against its reference path (docs/performance.md, "Where a loop's time goes").

A run of each case (``--levels``, ``dissipation="loop"``, one loop worker) records every
zone solve its loops make (the zone problem, load, state and guess); every
``--every``-th is then solved ``--repeat`` times, alternating:

``steps``
    as the package solves it: the block system of a set of pair states built once per
    solve (:class:`qsma.contact.linear.BlockSystem`, its LU factors reused by iterative
    refinement), the residual check skipped where a bound shows that it must fail
    (:func:`qsma.contact.active_set.surely_rejected`);
``reference``
    every Newton step's whole system gathered from ``K`` and solved afresh
    (``basket_system`` and ``solve_partitioned``), the residual evaluated at every
    iterate.

Per case: the solves, the median CPU milliseconds per solve (the fastest of the repeats
of each solve), their ratio, the Newton steps of both (equal when the paths take the
same steps), and the largest difference of ``d`` and ``lam`` relative to their size.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_loop_solves.py --cases brb:1 brb:2 \\
        lap-3d:1 --levels tip:log:1e-4:1e-3:3 --every 3 --repeat 3
"""
from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import qsma
import qsma.analysis.dissipation as dissipation
import qsma.contact.zone as zone_module
from qsma.cli.run import parse_levels_spec
from qsma.contact import active_set, solve
from qsma.contact.linear import basket_system, solve_partitioned
from qsma.examples import EXAMPLES


def recorded_solves(case, levels):
    """The zone solves of the loops of one run: ``(problem, lam_w, state, options)``."""
    name, refine = case.split(":")
    seen, loops = [], {"on": False}
    original = zone_module.solve

    def recorded(problem, lam_w, state=None, **kw):
        if loops["on"]:
            seen.append((problem, np.array(lam_w), state, kw))
        return original(problem, lam_w, state, **kw)

    compute_loop = dissipation.compute_loop

    def in_loops(*a, **k):
        loops["on"] = True
        try:
            return compute_loop(*a, **k)
        finally:
            loops["on"] = False

    zone_module.solve, dissipation.compute_loop = recorded, in_loops
    try:
        qsma.run(EXAMPLES[name](int(refine)), levels=parse_levels_spec(levels),
                 dissipation="loop", loop_workers=1)
    finally:
        zone_module.solve, dissipation.compute_loop = original, compute_loop
    return seen


def _reference_newton_point(self, sets):
    R, b, unknown, d_known = basket_system(self.problem, self.lw, sets.status, -sets.h,
                                           sets.alpha, self.prev, self.c)
    return solve_partitioned(R, b, unknown, d_known)


class _Reference:
    """The reference path while in the ``with`` block."""

    def __enter__(self):
        self.saved = (active_set._Newton._newton_point, active_set.surely_rejected)
        active_set._Newton._newton_point = _reference_newton_point
        active_set.surely_rejected = lambda *a, **k: False
        return self

    def __exit__(self, *exc):
        active_set._Newton._newton_point, active_set.surely_rejected = self.saved


def _timed(solves):
    out, seconds = [], []
    for problem, lam_w, state, kw in solves:
        t = time.process_time()
        res = solve(problem, lam_w, state, **kw)
        seconds.append(time.process_time() - t)
        out.append(res)
    return out, np.array(seconds)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", nargs="+", default=["brb:1", "lap-3d:1"])
    parser.add_argument("--levels", default="tip:log:1e-4:1e-3:3")
    parser.add_argument("--every", type=int, default=3)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    print("| case | solves | ms per solve, steps | reference | ratio | Newton steps "
          "(steps / reference) | max rel. diff d, lam |")
    print("|---|---|---|---|---|---|---|")
    for case in args.cases:
        solves = recorded_solves(case, args.levels)[::args.every]
        fast, slow = [], []
        for _ in range(args.repeat):
            ours, t_ours = _timed(solves)
            with _Reference():
                ref, t_ref = _timed(solves)
            fast.append(t_ours)
            slow.append(t_ref)
        t_ours, t_ref = np.min(fast, axis=0), np.min(slow, axis=0)
        diff = max(max(np.abs(a.d - b.d).max() / np.abs(b.d).max(),
                       np.abs(a.lam - b.lam).max() / np.abs(b.lam).max()) for a, b in zip(ours, ref))
        m_ours, m_ref = np.median(t_ours) * 1e3, np.median(t_ref) * 1e3
        print(f"| {case} | {len(solves)} | {m_ours:.2f} | {m_ref:.2f} | {m_ours / m_ref:.2f} | "
              f"{sum(r.nit for r in ours)} / {sum(r.nit for r in ref)} | {diff:.1e} |",
              flush=True)


if __name__ == "__main__":
    main()
