"""Time the static condensation of sandwich-2d per stage and refinement level.

Usage: python benchmarks/bench_condense.py [--refine 1 2 4 8] [--repeat 5]
       python benchmarks/bench_condense.py --solves 1 [--repeat 15]
       python benchmarks/bench_condense.py --memory 2 [--backend multifrontal]
       python benchmarks/bench_condense.py --combine 1000 3000 [--repeat 3]

Prints, per refinement: DOFs per body, interface DOFs, the Schur backend chosen
by "auto", and the median over ``--repeat`` runs of the factorisation, the Schur
complement, the rotation into pair frames (both bodies added) and the two-body
combination (K = Kc1 S^-1 Kc2, welded forces).

``--solves R`` times the K_EE solves of one sandwich-3d body at refine R (the
factor of the condensation, ``metis_superlu``) for several numbers of columns: the
solver as qsma calls it on 1 and 2 threads (``QSMA_SOLVE_THREADS``; one BLAS thread
inside either way) and the raw SuperLU solve with the process's BLAS threads (two
OpenBLAS threads on this machine: the setting before the solves were limited to one),
alternating (each timed call after an untimed one of the same setting, so that every
setting finds the factor in cache), medians of wall and CPU over ``--repeat`` rounds,
and whether the two thread counts give the same bits. Up to 11 columns the solver
does not split (``qsma.reduction.schur.SOLVE_MIN_COLUMNS``): those rows are the control.

``--memory R`` condenses the two bodies of sandwich-3d at refine R
(``reduce_two_bodies``) and prints the resident memory sampled every 20 ms, the
highest value per step (ordering, SuperLU factorisation, reading the factor until
scipy's copies are emptied, Schur update, the rest: rotation, loads and the two-body
combination) and the process peak (Linux ``VmHWM``). ``--backend`` chooses the
Schur backend (default ``auto``); with ``multifrontal`` the steps are the separator
tree, the factorisation with the Schur update, and the rest.

``--combine N ...`` times only the dense two-body combination on random SPD
matrices of size N: the direct ``Kc1 (Kc1 + Kc2)^-1 Kc2`` (Cholesky solve and
product) against ``qsma.reduction.two_bodies.minus_gram`` (``Kc1 - Y^T Y``, trsm + syrk), both
after the same Cholesky factorisation, median CPU and wall seconds over
``--repeat`` runs and the relative difference of the results.
"""
import argparse
import statistics
import time

import numpy as np
import scipy.linalg as sla

from qsma.reduction.two_bodies import minus_gram, reduce_two_bodies
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


def _timed(f):
    t0, c0 = time.perf_counter(), time.process_time()
    out = f()
    return out, time.perf_counter() - t0, time.process_time() - c0


def measure_combination(n, repeat):
    rng = np.random.default_rng(0)
    B1, B2 = rng.normal(size=(n, n)), rng.normal(size=(n, n))
    Kc1, Kc2 = B1 @ B1.T / n + np.eye(n), B2 @ B2.T / n + np.eye(n)
    S_cho = sla.cho_factor(Kc1 + Kc2)

    def direct():
        K = Kc1 @ sla.cho_solve(S_cho, Kc2)
        return 0.5 * (K + K.T)
    runs = [(_timed(direct), _timed(lambda: minus_gram(Kc1, S_cho, Kc1)))
            for _ in range(repeat)]
    (K_direct, *_), (K_gram, *_) = runs[-1]
    diff = np.abs(K_direct - K_gram).max() / np.abs(K_direct).max()
    med = lambda i, j: statistics.median(r[i][j] for r in runs)
    return med(0, 1), med(0, 2), med(1, 1), med(1, 2), diff


def measure_solves(refine, repeat, widths=(2, 6, 12, 24)):
    """Rows ``(width, {setting: (wall, cpu)}, same_bits)`` of :func:`main`'s
    ``--solves`` table."""
    import os
    from threadpoolctl import threadpool_limits
    from qsma.reduction.condensation import condense_body
    from qsma.examples import sandwich_3d
    from qsma.reduction.schur import nested_dissection
    import scipy.sparse.linalg as spla
    model = sandwich_3d(refine)
    a = assemble_body(model.bodies[0])
    body = condense_body(a, make_pairing(model).nodes1, make_pairing(model).frames)
    K = a.K.tocsr()[body.E][:, body.E]
    p = nested_dissection(K)
    with threadpool_limits(limits=1, user_api="blas"):
        lu = spla.splu(K[p][:, p].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    rng = np.random.default_rng(0)
    rows = []
    for w in widths:
        B = rng.standard_normal((body.solve_EE.n, w))
        Bp = np.asfortranarray(B[p])
        times, results = {}, {}
        for _ in range(repeat):
            for setting in ("1 thread", "2 threads", "raw, process BLAS"):
                if setting == "raw, process BLAS":
                    f = lambda: lu.solve(Bp)
                else:
                    os.environ["QSMA_SOLVE_THREADS"] = setting[0]
                    f = lambda: body.solve_EE(B)
                f()                               # warm: the factor back in cache
                out, wall, cpu = _timed(f)
                times.setdefault(setting, []).append((wall, cpu))
                results[setting] = out
        os.environ.pop("QSMA_SOLVE_THREADS", None)
        med = {k: (statistics.median(t[0] for t in v), statistics.median(t[1] for t in v))
               for k, v in times.items()}
        rows.append((w, med, bool(np.array_equal(results["1 thread"],
                                                 results["2 threads"]))))
    return body.solve_EE.n, rows


def measure_memory(refine, backend="auto"):
    """``(peaks per step in MiB, process peak in MiB, seconds)`` of condensing the
    two bodies of sandwich-3d at ``refine`` (steps named by wrapping functions of
    the metis_superlu and multifrontal backends)."""
    import threading
    from qsma._infra import resources as _resources
    from qsma.reduction.schur import metis_superlu as linalg
    from qsma.reduction.schur import multifrontal
    from qsma.examples import sandwich_3d
    model = sandwich_3d(refine)
    A = [assemble_body(b) for b in model.bodies]
    pairing = make_pairing(model)
    step, peaks, done = ["before"], {}, threading.Event()

    def sample():
        while not done.is_set():
            rss = _resources.current_memory_mb() or 0.0
            peaks[step[0]] = max(peaks.get(step[0], 0.0), rss)
            time.sleep(0.02)

    def labelled(name, function, after):
        def run(*args, **kwargs):
            step[0] = name
            try:
                return function(*args, **kwargs)
            finally:
                step[0] = after
        return run
    saved = {n: getattr(linalg, n) for n in
             ("nested_dissection", "_drop_extracted_factors", "_low_rank_sum")}
    saved_splu = linalg.spla.splu
    linalg.nested_dissection = labelled("ordering", saved["nested_dissection"], "ordering")
    linalg.spla.splu = labelled("factorisation", saved_splu, "reading the factor")
    linalg._drop_extracted_factors = labelled("reading the factor",
                                              saved["_drop_extracted_factors"], "schur")
    linalg._low_rank_sum = labelled("schur", saved["_low_rank_sum"], "the rest")
    saved_mf = {n: getattr(multifrontal, n) for n in ("front_structure",
                                                      "multifrontal_schur")}
    multifrontal.front_structure = labelled("separator tree",
                                            saved_mf["front_structure"], "the rest")
    multifrontal.multifrontal_schur = labelled(
        "factorisation and Schur update", saved_mf["multifrontal_schur"], "the rest")
    sampler = threading.Thread(target=sample, daemon=True)
    try:
        _resources.reset_peak()
        sampler.start()
        t0 = time.perf_counter()
        rm = reduce_two_bodies(A[0], A[1], pairing, backend=backend)
        seconds = time.perf_counter() - t0
    finally:
        done.set()
        sampler.join()
        for n, f in saved.items():
            setattr(linalg, n, f)
        for n, f in saved_mf.items():
            setattr(multifrontal, n, f)
        linalg.spla.splu = saved_splu
    return peaks, _resources.peak_memory_mb(), seconds, rm.bodies[0].timings["backend"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--combine", type=int, nargs="+", default=None)
    ap.add_argument("--solves", type=int, default=None, metavar="REFINE")
    ap.add_argument("--memory", type=int, default=None, metavar="REFINE")
    ap.add_argument("--backend", default="auto", help="Schur backend of --memory")
    args = ap.parse_args()
    if args.memory:
        peaks, peak, seconds, used = measure_memory(args.memory, args.backend)
        print(f"sandwich-3d refine {args.memory}, reduce_two_bodies ({used}): "
              f"{seconds:.1f} s, process peak (VmHWM) {peak:.0f} MiB\n")
        print("| step | highest resident memory sampled [MiB] |")
        print("|---|---|")
        for name, mb in peaks.items():
            print(f"| {name} | {mb:.0f} |")
        return
    if args.solves:
        n, rows = measure_solves(args.solves, args.repeat)
        print(f"sandwich-3d refine {args.solves}, K_EE of one body ({n} DOFs); wall / CPU "
              f"[ms], median of {args.repeat}\n")
        print("| columns | 1 thread | 2 threads | raw SuperLU, process BLAS threads | "
              "2 threads / 1 thread (wall) | same bits |")
        print("|---|---|---|---|---|---|")
        for w, med, same in rows:
            cell = lambda k: f"{1e3 * med[k][0]:.0f} / {1e3 * med[k][1]:.0f}"
            print(f"| {w} | {cell('1 thread')} | {cell('2 threads')} | "
                  f"{cell('raw, process BLAS')} | "
                  f"{med['2 threads'][0] / med['1 thread'][0]:.2f} | {same} |", flush=True)
        return
    if args.combine:
        print("| n | direct wall [s] | direct CPU [s] | Kc - Y^T Y wall [s] | "
              "Kc - Y^T Y CPU [s] | CPU ratio | rel. diff |")
        print("|---|---|---|---|---|---|---|")
        for n in args.combine:
            dw, dc, gw, gc, diff = measure_combination(n, args.repeat)
            print(f"| {n} | {dw:.3f} | {dc:.3f} | {gw:.3f} | {gc:.3f} | {dc / gc:.2f} | "
                  f"{diff:.1e} |", flush=True)
        return
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
