"""Time and peak memory of every available Schur complement backend (qsma.reduction.schur).

Usage: python benchmarks/bench_schur.py [--cases 2d-1 2d-2 2d-4 2d-8 3d-1 3d-2]
                                        [--repeat 3] [--backends ...] [--max-seconds 60]
       python benchmarks/bench_schur.py --stages --cases 3d-1 3d-2
                                        [--backends metis_superlu multifrontal] [--repeat 3]
       python benchmarks/bench_schur.py --solve-split --cases 3d-1 3d-2 [--repeat 5]

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

``--stages`` prints, per case, one row per backend with the medians of the stage
times that the backend reports (ordering, factorisation, Schur update), the total
wall and CPU time of ``schur_complement``, the peak memory, the Kc difference and the
wall time of ``K_EE`` solves of 1, 12 and 24 random columns through the returned
solver (as qsma calls it: ``QSMA_SOLVE_THREADS`` and one BLAS thread inside; each
median of 3 calls after an untimed one). The backends alternate within every round
(round 1: all backends, round 2: all backends, ...), so that a change in the load of
a shared machine reaches them alike.

``--solve-split`` factorises each case once with the ``multifrontal`` backend and
times its ``K_EE`` solve of 12, 16 and 24 random columns two ways, alternating: one
call on all the columns (what the backend does) and the columns split between two
Python threads (:func:`qsma.reduction.schur.solved_by_columns` with ``threads=2``),
both with one BLAS thread; medians of ``--repeat`` calls each. The factor's
loop over the fronts holds the GIL between BLAS calls, so the split can only lose.
"""
import argparse
import statistics
import time

import numpy as np

from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.reduction.schur import AUTO_ORDER, available_backends, schur_complement
from qsma.model import Body, Clamp, Material, make_pairing
from qsma.mesh.generate import graded_axis, structured_mesh

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


def solve_times(solver, widths=(1, 12, 24), calls=3):
    """Median wall seconds of ``solver(B)`` per width (after one untimed call)."""
    rng = np.random.default_rng(0)
    out = {}
    for w in widths:
        B = rng.standard_normal((solver.n, w)) if w > 1 else rng.standard_normal(solver.n)
        solver(B)
        times = []
        for _ in range(calls):
            t0 = time.perf_counter()
            solver(B)
            times.append(time.perf_counter() - t0)
        out[w] = statistics.median(times)
    return out


def staged_call(K, C, backend):
    """``measured_call`` plus the backend's stage times and the solve times."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    rss0 = _status_kb("VmRSS")
    t0, c0 = time.perf_counter(), time.process_time()
    Kc, solver = schur_complement(K, C, backend=backend)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    peak = (_status_kb("VmHWM") - rss0) / 1024
    return dict(solver.timings, wall=seconds, cpu=cpu, peak=peak,
                **{f"solve {w}": v for w, v in solve_times(solver).items()}), Kc


def main_stages(args):
    cols = ["ordering", "factorization", "schur", "wall", "cpu", "solve 1", "solve 12",
            "solve 24"]
    print("| case | backend | ordering [s] | factorisation [s] | Schur update [s] | total "
          "[s] | CPU [s] | peak memory [MB] | Kc rel. diff | solve 1 col [ms] | 12 cols "
          "[ms] | 24 cols [ms] |")
    print("|---" * 12 + "|")
    for case in args.cases:
        dim, refine = case.split("-")
        K, C = (case_2d if dim == "2d" else case_3d)(int(refine))
        runs = {b: [] for b in args.backends}
        ref, diff = None, {}
        for _ in range(args.repeat):
            for b in args.backends:
                row, Kc = staged_call(K, C, b)
                runs[b].append(row)
                ref = Kc if ref is None else ref
                diff[b] = max(diff.get(b, 0.0), np.abs(Kc - ref).max() / np.abs(ref).max())
                del Kc
        for b in args.backends:
            med = {c: statistics.median(r.get(c, 0.0) for r in runs[b]) for c in cols}
            peak = max(r["peak"] for r in runs[b])
            print(f"| {case} | {b} | {med['ordering']:.2f} | {med['factorization']:.2f} | "
                  f"{med['schur']:.2f} | {med['wall']:.2f} | {med['cpu']:.2f} | {peak:.0f} | "
                  f"{diff[b]:.1e} | {1e3 * med['solve 1']:.0f} | {1e3 * med['solve 12']:.0f} "
                  f"| {1e3 * med['solve 24']:.0f} |", flush=True)


def main_solve_split(args):
    import scipy.sparse as sp
    from qsma.reduction.schur import multifrontal
    from qsma.reduction.schur import solved_by_columns
    print("| case | columns | one call [ms] | two threads [ms] | two threads / one call |")
    print("|---|---|---|---|---|")
    rng = np.random.default_rng(0)
    for case in args.cases:
        dim, refine = case.split("-")
        K, C = (case_2d if dim == "2d" else case_3d)(int(refine))
        K = sp.csr_matrix(K)
        E = np.setdiff1d(np.arange(K.shape[0]), C)
        factor = multifrontal.schur_parts(K, C, E)[1]
        for width in (12, 16, 24):
            B = rng.standard_normal((len(E), width))
            times = {1: [], 2: []}
            for _ in range(args.repeat):
                for threads in (1, 2):
                    t0 = time.perf_counter()
                    solved_by_columns(factor.solve, B, threads=threads)
                    times[threads].append(time.perf_counter() - t0)
            one, two = (statistics.median(times[t]) for t in (1, 2))
            print(f"| {case} | {width} | {1e3 * one:.0f} | {1e3 * two:.0f} | "
                  f"{two / one:.2f} |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["2d-1", "2d-2", "2d-4", "2d-8", "3d-1"])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--backends", nargs="+",
                    default=[b for b in AUTO_ORDER if b in available_backends()])
    ap.add_argument("--max-seconds", type=float, default=60.0)
    ap.add_argument("--stages", action="store_true",
                    help="stage times, peak memory and K_EE solve times per backend")
    ap.add_argument("--solve-split", action="store_true",
                    help="multifrontal K_EE solves: one call against two column threads")
    args = ap.parse_args()
    if args.solve_split:
        return main_solve_split(args)
    K, C = case_2d(1)
    for b in args.backends:                           # warm-up: load libraries, threads
        schur_complement(K, C, backend=b)
    if args.stages:
        return main_stages(args)
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
