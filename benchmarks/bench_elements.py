"""Element choice per accuracy: time to the tied frequency f0 per element type.

Usage: python benchmarks/bench_elements.py [--example sandwich-2d|sandwich-3d]
           [--elements quad CPE4I quad8 quad9] [--refine 1 2 4] [--repeat 3] [--zeta]

For each element type and refinement: f0 (first bending mode of the structure tied
at the pairs closed after the bolt preload) and the wall time from the model to f0
(mesh generation, assembly, pairing, condensation, preload contact solve, tied
eigen solve), median of ``--repeat`` runs. The extrapolated limit of each element
family is Richardson's from its last three refinements, ``f_inf = f3 - (f3 - f2)^2 /
((f3 - f2) - (f2 - f1))`` (Aitken's delta-squared, no assumed order). ``--zeta`` also
runs the whole QSMA (51 levels) once per mesh and prints zeta at the last level.
"""
import argparse
import statistics
import time

import numpy as np

from qsma.analysis import preload
from qsma.examples import sandwich_2d, sandwich_3d
from qsma.fe import assemble_body
from qsma.modal import linear_modes
from qsma.model import make_pairing

EXAMPLES = {"sandwich-2d": sandwich_2d, "sandwich-3d": sandwich_3d}


def time_to_f0(make, refine, element):
    """``(f0 [Hz], seconds, n_nodes, n_pairs, formulation, n_closed)`` of one model."""
    t = time.perf_counter()
    model = make(refine, element=element)
    assembled = [assemble_body(b) for b in model.bodies]
    pairing = make_pairing(model)
    _, _, pre = preload(model, assembled, pairing)
    modes = linear_modes(model, assembled, pairing, tied=pre.status != 2, n_modes=1)
    return (float(modes.f_hz[0]), time.perf_counter() - t, model.n_nodes, pairing.n_pairs,
            assembled[0].formulation, int(np.sum(pre.status != 2)))


def aitken(f):
    """Delta-squared extrapolation of the last three values of a sequence."""
    f1, f2, f3 = f[-3:]
    d = (f3 - f2) - (f2 - f1)
    return f3 - (f3 - f2) ** 2 / d if d != 0 else f3


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--example", default="sandwich-2d", choices=sorted(EXAMPLES))
    ap.add_argument("--elements", nargs="+", default=None)
    ap.add_argument("--refine", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--zeta", action="store_true")
    args = ap.parse_args()
    make = EXAMPLES[args.example]
    elements = args.elements or (["quad", "CPE4I", "quad8", "quad9"]
                                 if args.example == "sandwich-2d"
                                 else ["hexahedron", "C3D8I", "hexahedron20"])
    print(f"{args.example}: f0 and time to f0 (median of {args.repeat} runs)")
    print("| element | refine | nodes | pairs | closed after preload | f0 [Hz] "
          "| time to f0 [s] |" + (" zeta last level |" if args.zeta else ""))
    print("|---|---|---|---|---|---|---|" + ("---|" if args.zeta else ""))
    rows = {}
    for el in elements:
        for r in args.refine:
            runs = [time_to_f0(make, r, el) for _ in range(args.repeat)]
            f0, _, nn, npair, form, closed = runs[-1]
            sec = statistics.median(x[1] for x in runs)
            rows.setdefault(el, []).append((r, f0, sec, form))
            z = ""
            if args.zeta:
                import qsma
                res = qsma.run(make(r, element=el))
                z = f" {res.zeta[-1]:.5f} |"
            print(f"| {el} | {r} | {nn} | {npair} | {closed} | {f0:.4f} | {sec:.3f} |{z}",
                  flush=True)
    print()
    for el, rr in rows.items():
        print(f"{el}: {rr[0][3]}")
        if len(rr) >= 3:
            print(f"  extrapolated f0 (Aitken, refine {rr[-3][0]}/{rr[-2][0]}/{rr[-1][0]}): "
                  f"{aitken([x[1] for x in rr]):.4f} Hz")


if __name__ == "__main__":
    main()
