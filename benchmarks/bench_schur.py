"""Time and peak memory of every available Schur complement backend (qsma.linalg).

Usage: python benchmarks/bench_schur.py [--cases 2d-1 2d-2 2d-4 2d-8 3d-1 3d-2]
                                        [--repeat 3] [--backends ...] [--max-seconds 60]

Cases: ``2d-R`` is the bottom beam of sandwich-2d at refine R (free DOFs, C = its
interface DOFs); ``3d-R`` is a clamped hexahedral block of the 3D sandwich size (63 x 5
x 17 nodes at R = 1, every element split R x R x R) condensed onto its face y = h for
x >= L - 0.0508. Per case and backend: the median wall time of ``--repeat`` calls of
``schur_complement`` (after one warm-up call on a small case), the median CPU time of
the process over the same calls (all threads: the fair measure on a shared machine),
and the peak resident
memory above the level before the call (Linux ``VmHWM`` after resetting it through
``/proc/self/clear_refs``; it counts the C libraries' allocations, which tracemalloc
does not see). A backend whose first call exceeds ``--max-seconds`` is run once and
skipped at the larger cases of the same dimension. Kc is checked against the first
backend of the row set (max |difference| / max |Kc|).
"""
import argparse
import statistics
import time

import numpy as np

from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.linalg import AUTO_ORDER, available_backends, schur_complement
from qsma.model import Body, Clamp, Material, make_pairing
from qsma.model.generate import graded_axis, structured_mesh

L, H, LC, WIDTH = 0.2032, 0.00635, 0.0508, 0.0254


def case_2d(refine):
    model = sandwich_2d(refine)
    a = assemble_body(model.bodies[0])
    dofs = (2 * make_pairing(model).nodes1[:, None] + np.arange(2)).ravel()
    return a.K.tocsr()[a.free][:, a.free], np.searchsorted(a.free, dofs)


def case_3d(refine):
    xs = graded_axis((0.0, L - LC, 30 * refine), (L - LC, L, 32 * refine))
    mesh = structured_mesh(xs, np.linspace(0, H, 4 * refine + 1),
                           np.linspace(0, WIDTH, 16 * refine + 1))
    p, eps = mesh.points, 1e-9 * L
    mesh = mesh.with_sets(node_sets={"clamp": np.flatnonzero(np.abs(p[:, 0]) < eps)})
    body = Body("block", mesh, Material(200e9, 0.285, 6600.0), clamps=(Clamp("clamp"),))
    a = assemble_body(body)
    nodes = np.flatnonzero((np.abs(p[:, 1] - H) < eps) & (p[:, 0] >= L - LC - eps))
    dofs = (3 * nodes[:, None] + np.arange(3)).ravel()
    return a.K.tocsr()[a.free][:, a.free], np.searchsorted(a.free, dofs)


def _status_kb(key):
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith(key + ":"))


def measured_call(K, C, backend):
    """(wall seconds, peak memory above the start [MB], Kc, CPU seconds) of one call."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")                                  # reset VmHWM to the current RSS
    rss0 = _status_kb("VmRSS")
    t0, c0 = time.perf_counter(), time.process_time()
    Kc, solver = schur_complement(K, C, backend=backend)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    peak = _status_kb("VmHWM") - rss0
    del solver
    return seconds, peak / 1024, Kc, cpu


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["2d-1", "2d-2", "2d-4", "2d-8", "3d-1"])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--backends", nargs="+",
                    default=[b for b in AUTO_ORDER if b in available_backends()])
    ap.add_argument("--max-seconds", type=float, default=60.0)
    args = ap.parse_args()
    K, C = case_2d(1)
    for b in args.backends:                           # warm-up: load libraries, threads
        schur_complement(K, C, backend=b)
    slow = set()
    print("| case | DOFs | interface DOFs | backend | time [s] (median) | CPU [s] (median) "
          "| runs | peak memory [MB] | Kc rel. diff |")
    print("|---|---|---|---|---|---|---|---|---|")
    for case in args.cases:
        dim, refine = case.split("-")
        K, C = (case_2d if dim == "2d" else case_3d)(int(refine))
        ref = None
        for b in args.backends:
            if (dim, b) in slow:
                print(f"| {case} | {K.shape[0]} | {len(C)} | {b} | skipped | | 0 | | |",
                      flush=True)
                continue
            runs = [measured_call(K, C, b)]
            if runs[0][0] > args.max_seconds:
                slow.add((dim, b))
            else:
                runs += [measured_call(K, C, b) for _ in range(args.repeat - 1)]
            Kc = runs[0][2]
            ref = Kc if ref is None else ref
            diff = np.abs(Kc - ref).max() / np.abs(ref).max()
            print(f"| {case} | {K.shape[0]} | {len(C)} | {b} | "
                  f"{statistics.median(r[0] for r in runs):.3f} | "
                  f"{statistics.median(r[3] for r in runs):.3f} | {len(runs)} | "
                  f"{max(r[1] for r in runs):.0f} | {diff:.1e} |", flush=True)
            del runs, Kc


if __name__ == "__main__":
    main()
