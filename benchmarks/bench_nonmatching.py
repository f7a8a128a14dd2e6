"""Non-matching sandwich-2d: convergence to the conforming answer, and the ramp cost.

Usage: python benchmarks/bench_nonmatching.py [--refine 1 2 4] [--top-fine 48]

The bottom beam is the sandwich-2d beam (64 refine elements along the contact zone);
the top beam is meshed with ``--top-fine`` x refine elements along the contact zone
(48: element 4/3 as long; a multiple of 16 keeps the bolt edges on nodes, so both
models carry the same bolt load). The interface is coupled by the dual mortar
projection (slave: the finer bottom side, 65 refine contact points, the same as the
conforming model). Prints, per refinement, f0 and zeta at a few load levels for the
conforming and the non-matching model, and the contact-stage seconds per level.
"""
import argparse
import dataclasses

import numpy as np

import qsma
from qsma.examples import sandwich_2d
from qsma.examples.sandwich import SANDWICH_2D
from qsma.mesh.generate import graded_axis, structured_mesh

LEVELS = (30, 40, 45, 50)


def nonmatching_sandwich(refine, top_fine):
    """sandwich-2d with the top beam remeshed along x in the contact zone."""
    s = SANDWICH_2D
    L, h, lc = s["L"], s["h"], s["contact_length"]
    model = sandwich_2d(refine)
    xs = graded_axis((0.0, L - lc, s["n_coarse"] * refine), (L - lc, L, top_fine * refine))
    mesh = structured_mesh(xs, np.linspace(h, 2 * h, s["n_thick"] * refine + 1))
    eps = 1e-9 * L
    xb0, xb1 = s["x_bolt"] - s["w_bolt"] / 2, s["x_bolt"] + s["w_bolt"] / 2
    on = lambda y: (lambda p: np.abs(p[:, 1] - y) < eps)
    mesh = mesh.with_sets(
        node_sets={"clamp": np.flatnonzero(np.abs(mesh.points[:, 0]) < eps),
                   "tip": np.flatnonzero(np.abs(mesh.points[:, 0] - L) < eps)},
        facet_sets={
            "interface": mesh.boundary_facets_where(
                lambda p: on(h)(p) & (p[:, 0] >= L - lc - eps)),
            "bolt": mesh.boundary_facets_where(
                lambda p: on(2 * h)(p) & (p[:, 0] >= xb0 - eps) & (p[:, 0] <= xb1 + eps)),
            "outer": mesh.boundary_facets_where(on(2 * h)),
            "end": mesh.boundary_facets_where(lambda p: np.abs(p[:, 0] - L) < eps)})
    top = dataclasses.replace(model.bodies[1], mesh=mesh)
    itf = dataclasses.replace(model.interface, coupling="mortar")
    return dataclasses.replace(model, bodies=(model.bodies[0], top), interface=itf,
                               name=f"sandwich-2d non-matching (refine={refine})")


def summary(res):
    per_level = res.timings_s["contact"] / (res.n_levels + 1)
    return dict(f0=res.f0_hz, zeta=[res.zeta[k] for k in LEVELS],
                f=[res.f_hz[k] for k in LEVELS], n=res.model_info["n_pairs"],
                closed=res.model_info["n_closed_after_preload"], sec=per_level,
                coupling=res.pairing.coupling)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--refine", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--top-fine", type=int, default=48)
    args = ap.parse_args(argv)
    rows = []
    for r in args.refine:
        for kind, model in (("conforming", sandwich_2d(r)),
                            ("non-matching", nonmatching_sandwich(r, args.top_fine))):
            res = qsma.run(model)
            if not res.success:
                raise SystemExit(f"{kind} refine {r}: {res.message}")
            rows.append((r, kind, summary(res)))
    head = " | ".join(f"zeta[{k}]" for k in LEVELS)
    print(f"| refine | model | contact points (closed) | f0 [Hz] | {head} | "
          f"contact s/level |")
    print("|---" * (5 + len(LEVELS)) + "|")
    for r, kind, s in rows:
        z = " | ".join(f"{v:.4e}" for v in s["zeta"])
        print(f"| {r} | {kind} | {s['n']} ({s['closed']}) | {s['f0']:.4f} | {z} | "
              f"{s['sec'] * 1e3:.2f} ms |")


if __name__ == "__main__":
    main()
