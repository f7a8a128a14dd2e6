"""What the loops cost where no pair with friction slips: frictionless joints.

    python benchmarks/bench_elastic_levels.py [DECK ...] [--repeat 3]

Runs ``qsma run`` (``-q --no-plots --no-vtu``, a process each) on the frictionless
lap joint ``--example lap-2d --mu 0`` and on each DECK given (e.g. ``hueeber1.inp`` of
the CalculiX source distribution's ``test/`` folder; nothing is fetched here; run with
``--density 7.85e-9``, the decks being in mm-N-s-tonne), twice per repeat: with the
default ``--dissipation auto``, where a level whose Masing checks fail but where no pair
with friction slipped is elastic and computes no loop, and with ``--dissipation loop``,
the loop at every level. On these models no level is Masing-verified (the pairs open,
close and slide from the preload on), so ``loop`` computes exactly the loops that
``auto`` computed before it knew the elastic levels. Prints per model and setting the
median wall-clock seconds of the process, the median ``timings_s`` of the run and of its
loops (``hysteresis``), the loop solves, the levels per method and the largest
|dissipation| reported, then the ratio of the medians.
"""
from __future__ import annotations

import argparse
from collections import Counter
import json
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile
import time


def run_once(source: list, dissipation: str) -> dict:
    """One ``qsma run`` of ``source`` (its arguments) with ``--dissipation``."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "qsma", "run", *source, "--out", f"{tmp}/out", "-q",
               "--no-plots", "--no-vtu", "--dissipation", dissipation]
        start = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - start
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
        res = json.loads(Path(tmp, "out", "results.json").read_text())
    levels = res["levels"]
    return dict(wall=wall, total=res["timings_s"]["total"],
                loops=res["timings_s"]["hysteresis"],
                solves=res["solver"]["loop_solves"],
                methods=dict(Counter(levels["dissipation_method"])),
                d_max=max(abs(d) for d in levels["dissipation"]))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("decks", nargs="*", help="CalculiX decks of frictionless joints")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    sources = {"lap-2d mu 0": ["--example", "lap-2d", "--mu", "0"]}
    sources.update({Path(d).name: [d, "--density", "7.85e-9"] for d in args.decks})
    print(f"{'model':<16} {'dissipation':<11} {'wall s':>7} {'run s':>7} {'loops s':>8} "
          f"{'solves':>7} {'max |D|':>8}  levels per method")
    for name, source in sources.items():
        medians = {}
        for dissipation in ("auto", "loop"):
            runs = [run_once(source, dissipation) for _ in range(args.repeat)]
            med = {k: statistics.median(r[k] for r in runs)
                   for k in ("wall", "total", "loops")}
            medians[dissipation] = med
            last = runs[-1]
            print(f"{name:<16} {dissipation:<11} {med['wall']:7.2f} {med['total']:7.2f} "
                  f"{med['loops']:8.3f} {last['solves']:7d} {last['d_max']:8.1e}  "
                  f"{last['methods']}")
        a, b = medians["auto"], medians["loop"]
        print(f"{name:<16} loop / auto: wall {b['wall'] / a['wall']:.1f}x, "
              f"run {b['total'] / a['total']:.1f}x")


if __name__ == "__main__":
    main()
