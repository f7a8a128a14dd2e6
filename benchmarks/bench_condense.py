"""Time the static condensation of sandwich-2d per stage and refinement level.

Usage: python benchmarks/bench_condense.py [--refine 1 2 4 8] [--repeat 5]

Prints, per refinement: DOFs per body, interface DOFs, and the median over
``--repeat`` runs of partition, factorisation of K_EE (SuperLU), multi-RHS solve
K_EE^-1 K_EC, Schur product, per body (both bodies added), and the two-body
combination; plus the peak memory of the dense K_EE^-1 K_EC block.
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
        per = {k: sum(b.timings[k] for b in rm.bodies) for k in rm.bodies[0].timings}
        per["combination"] = total - sum(per.values())
        per["total"] = total
        rows.append(per)
    med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
    n_e = len(rm.bodies[0].E)
    n_c = len(rm.bodies[0].C)
    return dict(refine=refine, dofs=A[0].n_dofs, nc=n_c, mem_mb=n_e * n_c * 8 / 2**20, **med)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    cols = ["partition", "factorization", "multi_rhs_solve", "schur", "combination", "total"]
    print(f"| refine | DOFs/body | interface DOFs | " + " | ".join(f"{c} [s]" for c in cols)
          + " | dense block [MB] |")
    print("|---" * (len(cols) + 4) + "|")
    for r in args.refine:
        m = measure(r, args.repeat if r < 8 else max(1, args.repeat // 2))
        print(f"| {r} | {m['dofs']} | {m['nc']} | "
              + " | ".join(f"{m[c]:.4f}" for c in cols) + f" | {m['mem_mb']:.1f} |",
              flush=True)


if __name__ == "__main__":
    main()
