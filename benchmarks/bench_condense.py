"""Time the static condensation of sandwich-2d per stage and refinement level.

Usage: python benchmarks/bench_condense.py [--refine 1 2 4 8] [--repeat 5]

Prints, per refinement: DOFs per body, interface DOFs, the Schur backend chosen
by "auto", and the median over ``--repeat`` runs of the factorisation, the Schur
complement, the rotation into pair frames (both bodies added) and the two-body
combination (K = Kc1 S^-1 Kc2, welded forces).
"""
import argparse
import statistics
import time

import numpy as np

from qsma.condense import reduce_two_bodies
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.model import make_pairing


def measure(refine, repeat):
    model = sandwich_2d(refine)
    A = [assemble_body(b) for b in model.bodies]
    p = make_pairing(model)
    rows = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        rm = reduce_two_bodies(A[0], A[1], p)
        total = time.perf_counter() - t0
        per = {k: sum(b.timings.get(k, 0.0) for b in rm.bodies)
               for k in ("factorization", "schur", "rotation")}
        per["combination"] = total - sum(b.timings["total"] + b.timings["rotation"]
                                         for b in rm.bodies)
        per["total"] = total
        rows.append(per)
    med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
    n_e = len(rm.bodies[0].E)
    n_c = len(rm.bodies[0].C)
    return dict(refine=refine, dofs=A[0].n_dofs, nc=n_c, backend=rm.bodies[0].timings["backend"],
                **med)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    cols = ["factorization", "schur", "rotation", "combination", "total"]
    print(f"| refine | DOFs/body | interface DOFs | backend | "
          + " | ".join(f"{c} [s]" for c in cols) + " |")
    print("|---" * (len(cols) + 4) + "|")
    for r in args.refine:
        m = measure(r, args.repeat if r < 8 else max(1, args.repeat // 2))
        print(f"| {r} | {m['dofs']} | {m['nc']} | {m['backend']} | "
              + " | ".join(f"{m[c]:.4f}" for c in cols) + " |", flush=True)


if __name__ == "__main__":
    main()
