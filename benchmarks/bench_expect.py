"""The pairs expected to close, let into the contact zone before a solve: with and
without, alternating in one process, on the Gmsh tetrahedral lap joint.

Usage: python benchmarks/bench_expect.py [--part ramps|loops] [--repeat 2]
           [--levels tip:log:1e-4:1e-3:2]

``ramps``: the two ramps with ``dissipation="masing"`` forced (51 levels, refined),
without and with the straight-line extrapolation of the openings
(``qsma.analysis._expected_closing``). ``loops``: the loops at ``--levels`` with
``dissipation="loop"``, without and with the pairs closed a cycle before
(``compute_loop(..., expect_closing=True)``). Both serial (the -alpha ramp in this
process, one loop worker), so that the two sides do the same work on one core. Each
side of a pair gets a fresh preload and contact problem on one preparation (the tied
modes reused). Prints the wall seconds of the contact and hysteresis stages, the zone
solves (``qsma.contact.zone.solve`` calls) and the largest relative difference of
zeta, f and q between the two sides.

Needs the ``gmsh`` Python package, as benchmarks/bench_tet_lap.py.
"""
import argparse
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_tet_lap import tet_lap_model  # noqa: E402

import qsma.analysis as analysis  # noqa: E402
import qsma.contact.zone as zone  # noqa: E402
from qsma.cli.run import parse_levels_spec  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--part", choices=("ramps", "loops"), default="ramps")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--levels", default="tip:log:1e-4:1e-3:2",
                    help="with --part loops: as qsma run --levels")
    args = ap.parse_args()
    scratch = tempfile.TemporaryDirectory(prefix="expect_")    # the .msh files
    model = tet_lap_model(Path(scratch.name), 1.08, 1.25, 1.0)
    prepared = analysis.prepare(model)
    options = dict(parallel_ramps=False, loop_workers=1)
    if args.part == "ramps":
        options["dissipation"] = "masing"
    else:
        options.update(dissipation="loop", levels=parse_levels_spec(args.levels))
    analysis.run_prepared(prepared, **options)
    modes = {k: v for k, v in prepared.cache.items() if k[0] == "mode"}

    solves = [0]
    inner = zone.solve

    def counted(*a, **k):
        solves[0] += 1
        return inner(*a, **k)
    zone.solve = counted
    loop = analysis.dissipation.compute_loop
    # the part measured is switched off on the "without" side, the other stays on; each
    # name is patched in the module that calls it
    where = analysis.ramps if args.part == "ramps" else analysis.dissipation
    off = (dict(_expected_closing=lambda *a: None) if args.part == "ramps" else
           dict(compute_loop=lambda *a, **k: loop(*a, **{**k, "expect_closing": False})))
    sides = {"without": off, "with": {name: getattr(where, name) for name in off}}
    rows, last = {name: [] for name in sides}, {}
    for _ in range(args.repeat):
        for name, patch in sides.items():
            for attr, value in patch.items():
                setattr(where, attr, value)
            solves[0] = 0
            t0 = time.perf_counter()
            res = analysis.run_prepared(replace(prepared, cache=dict(modes)), **options)
            rows[name].append((time.perf_counter() - t0, res.timings_s["contact"],
                               res.timings_s["hysteresis"], solves[0]))
            last[name] = res
            print(f"{name}: wall {rows[name][-1][0]:.2f} s, contact "
                  f"{rows[name][-1][1]:.2f} s, hysteresis {rows[name][-1][2]:.2f} s, "
                  f"zone solves {solves[0]}, success {res.success}", flush=True)
    for attr, value in sides["with"].items():
        setattr(where, attr, value)
    print()
    print(f"{model.name}, part {args.part}: medians of {args.repeat}")
    print("| side | wall [s] | contact [s] | hysteresis [s] | zone solves |")
    print("|---|---|---|---|---|")
    for name, values in rows.items():
        med = [statistics.median(v[i] for v in values) for i in range(4)]
        print(f"| {name} | {med[0]:.2f} | {med[1]:.2f} | {med[2]:.2f} | {med[3]:.0f} |")
    ratios = [w[0] / o[0] for w, o in zip(rows["with"], rows["without"])]
    print("wall with / without, pair by pair: " + ", ".join(f"{r:.2f}" for r in ratios))
    a, b = last["without"], last["with"]
    rel = lambda x, y: float(np.nanmax(np.abs(x - y) / np.abs(x)))
    print(f"largest relative difference: zeta {rel(a.zeta, b.zeta):.1e}, "
          f"f {rel(a.f_hz, b.f_hz):.1e}, q {rel(a.q, b.q):.1e}; stuck/slip/open equal: "
          f"{np.array_equal(a.n_slip, b.n_slip) and np.array_equal(a.n_open, b.n_open)}")


if __name__ == "__main__":
    main()
