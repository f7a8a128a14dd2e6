"""Computed loops on lap joints: where the solves go, loops on two processes, and
whether D could be interpolated between a subset of the levels.

Three tables (docs/performance.md, "The real joints: lap joints and the Brake-Reuss
beam" and "Loops on several processes"; the interpolation: CHANGELOG.md, "Tried and
not kept"):

``profile``
    One run per case: per computed loop, the cycles on the initial increments until
    one repeated, the solves they took, the solves of the refinement rounds and the
    final increments per branch.
``parallel``
    ``--repeat`` runs of each case with the loops in the process, on ``--workers``
    forked processes and on a local Dask cluster of ``--workers`` processes
    (``loop_scheduler``; scheduler and workers started as their own processes),
    alternating, each run in a fresh interpreter; the median of the hysteresis stage
    and the speed-up, the median CPU seconds of the run's process and its children (a
    Dask worker's CPU is not counted there), and whether every per-level value and
    every loop point has the same bits as in one process.
``scaling``
    One run of each case with every loop in the process: the loops' wall time on N
    workers (``--scaling-workers``) when the longest loops are handed out first, as the
    run does, and the whole run's speed-up with the rest of it (model, condensation,
    ramps) serial.
``methods``
    ``--repeat`` runs of each case with every method of ``--methods`` (one loop worker,
    alternating); the median of the hysteresis and the contact stages, the ratio to the
    first method, the loop solves, and the largest relative difference of the loops'
    zeta from the first method's.
``warm``
    ``--repeat`` runs of each case with one loop worker, alternating: the loops' solves
    started from the state reached at the same load a cycle before (the default,
    ``warm_start``) and from the previous point of the cycle only; per side the median
    CPU seconds of the run (the ramps are the same on both sides), the iterations of
    the loops' contact solves, and the largest relative difference of the loops' D and
    zeta between the two (both meet the contact tolerance; the bits differ).
``settle``
    The same for the refinement rounds: the intervals whose share of the loop settled
    are no longer halved (the default) against every interval where a pair changes
    state halved in every round; also the largest difference of D in units of the
    larger error estimate.
``interpolation``
    From one run (the levels with computed loops): loops at every ``stride``-th level, the
    others interpolated by PCHIP of ``log D`` and ``log q_a`` in ``log A`` where the
    leave-one-out estimate (each computed node predicted from the other nodes) of the
    two bounding nodes is below ``rtol``, more levels computed until it is; the loops
    this saves, and the worst error of the interpolated zeta against the computed one,
    also in units of its estimate.

    python benchmarks/bench_loops.py profile --cases lap-3d:1
    python benchmarks/bench_loops.py parallel --cases lap-3d:1 --repeat 2 \
        --dissipation loop --workers 2
    python benchmarks/bench_loops.py scaling --cases lap-3d:1 brb:2
    python benchmarks/bench_loops.py methods --cases lap-3d:1 brb:1 --repeat 2 \
        --levels tip:log:1e-4:1e-3:2 --dissipation loop
    python benchmarks/bench_loops.py interpolation --cases lap-2d:1 lap-3d:1 brb:1
    python benchmarks/bench_loops.py warm --cases brb:1 lap-3d:1 \
        --levels tip:log:1e-5:1e-3:5 --dissipation loop --repeat 3
    python benchmarks/bench_loops.py settle --cases brb:1 lap-3d:1 \
        --levels tip:log:1e-5:1e-3:5 --dissipation loop --repeat 2

Measured on the shared two-core machine (load average 2 to 8; medians of the CPU of
the run, the ramps the same on both sides):

| table | case | loops | loop solves | contact iterations | CPU [s] | ratio | D apart / estimate |
|---|---|---|---|---|---|---|---|
| warm (3 repeats) | brb:1 | 5 | 668 / 668 | 1983 / 2171 | 2.69 / 2.61 | 1.03 | - |
| warm (3 repeats) | lap-3d:1 | 5 | 1042 / 1042 | 3654 / 4260 | 5.09 / 5.41 | 0.94 | D, zeta to 6e-11 |
| settle (2 repeats) | brb:1 | 5 | 722 / 668 | 2140 / 1983 | 2.83 / 2.48 | 1.14 | 0.28 |
| settle (2 repeats) | lap-3d:1 | 5 | 1012 / 1042 | 3562 / 3654 | 5.48 / 5.63 | 0.97 | 0.04 |

On five levels one BRB loop needs a fourth refinement round with the settled intervals
(their bound, added to the estimate, pushed it just above the tolerance); over the 51
default levels (``dissipation="auto"``) the settled intervals take the loop solves
from 6052 to 5616 (BRB refine 1), 15112 to 13726 (lap-3d refine 1) and 7094 to 6154
(BRB refine 2).
"""
from __future__ import annotations

import argparse
import os
import statistics

import numpy as np

import qsma
from qsma._infra.resources import cpu_with_children_s
from qsma.cli.run import parse_levels_spec
from qsma.examples import EXAMPLES
from qsma.analysis.result import LEVEL_FIELDS

#: A computed loop is an interpolation node if D exceeds this multiple of (its error
#: estimate + the zero threshold zeta 1e-8): log D of a zero-to-its-error value is noise.
NODE_MARGIN = 10.0


def _run(case, levels, **options):
    name, refine = case.split(":")
    kw = {} if levels is None else dict(levels=parse_levels_spec(levels))
    return qsma.run(EXAMPLES[name](int(refine)), **kw, **options)


def _header(*columns):
    print("| " + " | ".join(columns) + " |")
    print("|---" * len(columns) + "|")


def profile(args):
    _header("case", "level", "A", "cycles", "solves of the cycles",
            "solves of the refinement", "increments per branch (initial -> final)", "D",
            "error / D")
    for case in args.cases:
        r = _run(case, args.levels, dissipation=args.dissipation)
        total = [0, 0]
        for k, lp in sorted(r.loops.items()):
            n_final = (len(lp.q) - 1) // 2
            n_initial = _initial_steps(r, k)
            cycles = lp.n_cycles * 2 * n_initial
            total[0] += cycles
            total[1] += lp.n_solves - cycles
            print(f"| {case} | {k} | {lp.amplitude:.4g} | {lp.n_cycles} | {cycles} | "
                  f"{lp.n_solves - cycles} | {n_initial} -> {n_final} | "
                  f"{lp.dissipation:.3e} | {lp.error / abs(lp.dissipation):.1e} |")
        t = r.timings_s
        print(f"| {case} | all {len(r.loops)} | | | {total[0]} | {total[1]} | | | |")
        print(f"\n{case}: hysteresis {t['hysteresis']:.1f} s, contact {t['contact']:.1f} s, "
              f"total {t['total']:.1f} s; {sum(total)} loop solves, "
              f"{t['hysteresis'] / max(sum(total), 1) * 1e3:.1f} ms per solve\n")


def _initial_steps(r, k):
    """Increments per branch of the first cycles of level k's loop (as the analysis
    chose them)."""
    from types import SimpleNamespace
    from qsma.analysis import _linear_end, _loop_fractions
    bb = r.backbone_states
    g = int(r.backbone_index[k])
    linear_end = _linear_end(SimpleNamespace(status=bb.status, n=len(bb.status)), r.preload)
    return len(_loop_fractions(r.backbone_alpha, g, linear_end, r.options.loop_steps))


def _digest(res) -> str:
    """SHA-256 of every per-level value and every loop's points of ``res``: two runs
    with the same digest gave the same bits."""
    import hashlib
    h = hashlib.sha256()
    for name in LEVEL_FIELDS:
        x = getattr(res, name)
        if isinstance(x, np.ndarray) and x.dtype.kind == "f":
            h.update(np.ascontiguousarray(x).tobytes())
        else:
            h.update(repr(list(x)).encode())
    for k in sorted(res.loops):
        h.update(np.ascontiguousarray(res.loops[k].q).tobytes())
    return h.hexdigest()


def _measured(case, levels, options):
    """One run in this (fresh) process: its hysteresis seconds, the CPU of the process
    and its children, the loops, the loop solves and the digest of its bits."""
    cpu = cpu_with_children_s()
    r = _run(case, levels, **options)
    return dict(hysteresis=r.timings_s["hysteresis"], cpu=cpu_with_children_s() - cpu,
                loops=len(r.loops), solves=r.solver["loop_solves"], digest=_digest(r))


def parallel(args):
    """Each case with the loops in one process, on ``--workers`` forked processes and
    on the workers of a local Dask cluster of as many processes, alternating.

    Every run is a fresh interpreter (``spawn``): a process that holds a Dask client or
    cluster has threads, and qsma forks no loop worker from such a process (the loops
    would run in it, one at a time). The cluster's scheduler and workers are
    processes of their own (``dask scheduler``, ``dask worker``), started once."""
    import concurrent.futures
    import multiprocessing
    import shutil
    import subprocess
    import sys
    import time
    n = args.workers
    sides = {"1 process": dict(loop_workers=1), f"{n} processes": dict(loop_workers=n)}
    dask = shutil.which("dask", path=os.path.dirname(sys.executable)) or shutil.which("dask")
    cluster = []
    if dask is None:
        print("(no `dask` command: the Dask rows are left out)")
    else:
        port = 18786
        address = f"tcp://127.0.0.1:{port}"
        quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        cluster.append(subprocess.Popen([dask, "scheduler", "--port", str(port),
                                         "--dashboard-address", ":0"], **quiet))
        time.sleep(2.0)
        cluster.append(subprocess.Popen([dask, "worker", address, "--nworkers", str(n),
                                         "--nthreads", "1", "--no-dashboard"], **quiet))
        time.sleep(4.0)
        sides[f"Dask, {n} workers"] = dict(loop_scheduler=address)
    _header("case", "loops", "loop solves", "loops on", "hysteresis [s]", "speed-up",
            "CPU of the run's processes [s]", "same bits as 1 process")
    context = multiprocessing.get_context("spawn")
    try:
        for case in args.cases:
            got = {s: [] for s in sides}
            for _ in range(args.repeat):
                for side, kw in sides.items():
                    with concurrent.futures.ProcessPoolExecutor(1, mp_context=context) as ex:
                        got[side].append(ex.submit(_measured, case, args.levels,
                                                   dict(kw, dissipation=args.dissipation)
                                                   ).result())
            first = got["1 process"][0]
            t1 = statistics.median(g["hysteresis"] for g in got["1 process"])
            for side, runs in got.items():
                t = statistics.median(g["hysteresis"] for g in runs)
                same = all(g["digest"] == first["digest"] for g in runs)
                print(f"| {case} | {first['loops']} | {first['solves']} | {side} | "
                      f"{t:.2f} | {t1 / t:.2f} | "
                      f"{statistics.median(g['cpu'] for g in runs):.1f} | "
                      f"{'yes' if same else 'NO'} |", flush=True)
    finally:
        for proc in cluster[::-1]:
            proc.terminate()
            proc.wait(timeout=30)


def _makespan(seconds, n) -> float:
    """Wall time of jobs of ``seconds`` on ``n`` workers, the longest handed out first
    (what :func:`qsma.hysteresis.workers.map_loops` does): each goes to the worker that
    is free first."""
    import heapq
    free = [0.0] * n
    for t in sorted(seconds, reverse=True):
        heapq.heappush(free, heapq.heappop(free) + t)
    return max(free)


def scaling(args):
    """From one run per case with every loop in this process: the loops' wall time on
    N workers by the longest-first rule, and the run's speed-up with the rest serial."""
    counts = [int(c) for c in args.scaling_workers]
    _header("case", "loops", "loops serial [s]", "longest loop [s]", "rest of the run [s]",
            *[f"N = {c}: loops [s] / run speed-up" for c in counts])
    for case in args.cases:
        r = _run(case, args.levels, dissipation=args.dissipation, loop_workers=1)
        loops = [t for t in r.level_costs.loop_seconds if t > 0]
        rest = r.timings_s["total"] - r.timings_s["hysteresis"]
        serial = rest + sum(loops)
        cells = []
        for c in counts:
            m = _makespan(loops, c)
            cells.append(f"{m:.2f} / {serial / (rest + m):.2f}")
        print(f"| {case} | {len(loops)} | {sum(loops):.2f} | {max(loops, default=0):.2f} | "
              f"{rest:.2f} | " + " | ".join(cells) + " |", flush=True)


def methods(args):
    _header("case", "method (ran)", "loops", "loop solves", "hysteresis [s]", "contact [s]",
            "hysteresis / first method's", "max rel. diff of zeta (loops)")
    for case in args.cases:
        hyst = {m: [] for m in args.methods}
        contact = {m: [] for m in args.methods}
        runs = {}
        for _ in range(args.repeat):
            for m in args.methods:
                runs[m] = _run(case, args.levels, dissipation=args.dissipation,
                               loop_workers=1, method=m)
                hyst[m].append(runs[m].timings_s["hysteresis"])
                contact[m].append(runs[m].timings_s["contact"])
        first = args.methods[0]
        h0 = statistics.median(hyst[first])
        for m in args.methods:
            r, z0 = runs[m], runs[first].zeta_loop
            ok = np.isfinite(z0) & (z0 != 0)
            diff = float(np.max(np.abs(r.zeta_loop[ok] / z0[ok] - 1), initial=0.0))
            h = statistics.median(hyst[m])
            ran = r.solver["method"]
            name = m if ran == m else f"{m} ({ran})"
            print(f"| {case} | {name} | {len(r.loops)} | "
                  f"{r.solver['loop_solves']} | {h:.2f} | "
                  f"{statistics.median(contact[m]):.2f} | {h / h0:.2f} | {diff:.1e} |",
                  flush=True)


def warm(args):
    """Loops warm-started from the cycle before against loops started from the previous
    point only, alternating in one process."""
    from qsma.analysis import dissipation          # where the loops are computed
    loop = dissipation.compute_loop

    def side(on):
        dissipation.compute_loop = lambda *a, **k: loop(*a, **{**k, "warm_start": on})
    try:
        _alternating(args, side, "from the cycle before", "from the previous point")
    finally:
        dissipation.compute_loop = loop


def settle(args):
    """Refinement rounds that stop halving the intervals whose share of the loop has
    settled (the default ``LOCAL_SHARE``) against rounds that halve every interval
    where a pair changes state (``LOCAL_SHARE = 0``), alternating in one process."""
    from qsma.hysteresis import refinement as hysteresis
    share = hysteresis.LOCAL_SHARE

    def side(on):
        hysteresis.LOCAL_SHARE = share if on else 0.0
    try:
        _alternating(args, side, f"settled intervals kept ({share:g} of the tolerance)",
                     "every changed interval halved")
    finally:
        hysteresis.LOCAL_SHARE = share


def _alternating(args, side, name_on, name_off):
    """``--repeat`` runs of each case with one loop worker, ``side(True)`` and
    ``side(False)`` alternating (the model prepared once); per side the median CPU
    seconds of the run, the loop solves, the iterations of all contact solves (the
    ramps' are the same on both sides), and the largest relative difference of the
    loops' D and zeta between the sides and the largest ``|D_on - D_off|`` over the
    larger of the two error estimates."""
    import time
    from qsma import analysis
    from qsma.contact import zone
    _header("case", "loops", "loop solves", "side", "CPU of the run [s]",
            "iterations of the contact solves (ramps included)", "CPU / second side's",
            "max rel. diff of D, zeta", "max \\|D_1 - D_2\\| / estimate")
    solve = zone.solve
    nit = [0]

    def counted(*a, **k):
        out = solve(*a, **k)
        nit[0] += out.nit
        return out
    zone.solve = counted
    try:
        for case in args.cases:
            name, refine = case.split(":")
            prepared = analysis.prepare(EXAMPLES[name](int(refine)))
            kw = dict(dissipation=args.dissipation, loop_workers=1, parallel_ramps=False)
            if args.levels:
                kw["levels"] = parse_levels_spec(args.levels)
            cpu = {True: [], False: []}
            its, runs = {}, {}
            for _ in range(args.repeat):
                for on in (True, False):
                    side(on)
                    nit[0], t = 0, time.process_time()
                    runs[on] = analysis.run_prepared(prepared, **kw)
                    cpu[on].append(time.process_time() - t)
                    its[on] = nit[0]
            a, b = runs[True], runs[False]
            ok = np.array([k in a.loops and a.loops[k].success and k in b.loops
                           and b.loops[k].success for k in range(a.n_levels)])
            rel = lambda x, y: float(np.max(np.abs(x[ok] - y[ok]) / np.maximum(
                np.abs(y[ok]), np.finfo(float).tiny), initial=0.0))
            diff = max(rel(a.dissipation_loop, b.dissipation_loop),
                       rel(a.zeta_loop, b.zeta_loop))
            est = np.maximum(a.dissipation_error, b.dissipation_error)[ok]
            off = np.abs(a.dissipation_loop - b.dissipation_loop)[ok]
            units = float(np.max(off / np.maximum(est, np.finfo(float).tiny), initial=0.0))
            c_on, c_off = statistics.median(cpu[True]), statistics.median(cpu[False])
            for on, c in ((True, c_on), (False, c_off)):
                r = runs[on]
                print(f"| {case} | {len(r.loops)} | {r.solver['loop_solves']} | "
                      f"{name_on if on else name_off} | {c:.2f} | {its[on]} | "
                      f"{c / c_off:.2f} | {diff:.1e} | {units:.2f} |", flush=True)
    finally:
        zone.solve = solve


def _same_bits(a, b):
    for name in LEVEL_FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, np.ndarray) and x.dtype.kind == "f":
            if not np.array_equal(x, y, equal_nan=True):
                return False
        elif list(x) != list(y):
            return False
    return all(np.array_equal(lp.q, b.loops[k].q) for k, lp in a.loops.items())


# -- the interpolation study --------------------------------------------------------------

def _pchip(x, y, at):
    from scipy.interpolate import PchipInterpolator
    return PchipInterpolator(x, y, extrapolate=False)(at)


def _is_node(lp, atol):
    return bool(lp.success and np.isfinite(lp.error)
                and lp.dissipation > NODE_MARGIN * (lp.error + atol))


def _runs(loops, computed, atol):
    """Computed indices in runs of consecutive nodes (a non-node ends a run)."""
    runs, run = [], []
    for i in sorted(computed):
        if _is_node(loops[i], atol[i]):
            run.append(i)
        else:
            runs.append(run)
            run = []
    return [r for r in runs + [run] if r]


def _xyz(A, loops, idx):
    return (np.log(A[idx]), np.log([loops[i].dissipation for i in idx]),
            np.log([loops[i].q_amplitude for i in idx]))


def _leave_one_out(A, loops, run, c):
    pos = run.index(c)
    if pos in (0, len(run) - 1):
        return np.nan
    x, y, z = _xyz(A, loops, run[:pos] + run[pos + 1:])
    xc, yc, zc = _xyz(A, loops, [c])
    return float(abs(_pchip(x, y, xc[0]) - yc[0]) + abs(_pchip(x, z, xc[0]) - zc[0]))


def _plan(A, loops, computed, atol, rtol):
    """{(a, b): estimate or inf} for consecutive computed levels with levels between."""
    run_of = {i: run for run in _runs(loops, computed, atol) for i in run}
    order = sorted(computed)
    plan = {}
    for a, b in zip(order[:-1], order[1:]):
        if b - a < 2:
            continue
        run = run_of.get(a)
        if run is None or run_of.get(b) is not run:
            plan[(a, b)] = np.inf
            continue
        e = [v for v in (_leave_one_out(A, loops, run, c) for c in (a, b)) if np.isfinite(v)]
        plan[(a, b)] = max(e) if e else np.inf
    return plan


def sparse(A, loops, atol, rtol, stride):
    """Computed indices and {level: (zeta, relative estimate)} of the interpolated ones."""
    n = len(A)
    computed = set(range(0, n, stride)) | {n - 1}
    while True:
        plan = _plan(A, loops, computed, atol, rtol)
        more = {(a + b) // 2 for (a, b), e in plan.items() if not e <= rtol}
        if not more:
            break
        computed |= more
    out = {}
    for (a, b), e in plan.items():
        run = next(r for r in _runs(loops, computed, atol) if a in r)
        x, y, z = _xyz(A, loops, run)
        node = max(loops[c].error / loops[c].dissipation for c in (a, b))
        for i in range(a + 1, b):
            D, qa = np.exp(_pchip(x, y, np.log(A[i]))), np.exp(_pchip(x, z, np.log(A[i])))
            out[i] = (D / (2 * np.pi * A[i] * qa), e + node)
    return computed, out


def interpolation(args):
    _header("case", "loops", "rtol", "stride", "computed", "solves (share)",
            "worst rel. error of zeta", "worst error / estimate")
    for case in args.cases:
        r = _run(case, args.levels, dissipation=args.dissipation)
        keys = sorted(k for k, lp in r.loops.items())
        loops = [r.loops[k] for k in keys]
        A = np.array([lp.amplitude for lp in loops])
        atol = np.array([1e-8 * 2 * np.pi * lp.amplitude * abs(lp.q_top) for lp in loops])
        total = sum(lp.n_solves for lp in loops)
        for rtol in args.rtols:
            for stride in args.strides:
                computed, interp = sparse(A, loops, atol, rtol, stride)
                solves = sum(loops[i].n_solves for i in computed)
                err = [abs(z / loops[i].zeta - 1) for i, (z, _) in interp.items()]
                ratio = [abs(z / loops[i].zeta - 1) / e for i, (z, e) in interp.items()]
                print(f"| {case} | {len(loops)} | {rtol:g} | {stride} | {len(computed)} | "
                      f"{solves} ({solves / total:.2f}) | "
                      f"{max(err, default=0):.2e} | {max(ratio, default=0):.2f} |",
                      flush=True)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("table", choices=["profile", "parallel", "scaling", "methods",
                                     "interpolation", "warm", "settle"])
    p.add_argument("--cases", nargs="+", default=["lap-2d:1"], help="EXAMPLE:REFINE")
    p.add_argument("--levels", help="levels spec (default: the 51 default levels)")
    p.add_argument("--dissipation", default="auto", choices=["auto", "loop"])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--workers", type=int, default=2,
                   help="processes of the parallel table (forked, and Dask workers)")
    p.add_argument("--scaling-workers", nargs="+", default=[1, 2, 4, 8, 16, 32, 64],
                   help="worker counts of the scaling table")
    p.add_argument("--methods", nargs="+", default=["basket", "active_set"],
                   help="contact methods of the methods table")
    p.add_argument("--rtols", type=float, nargs="+", default=[5e-3, 2e-2, 5e-2])
    p.add_argument("--strides", type=int, nargs="+", default=[2, 4, 8])
    args = p.parse_args(argv)
    {"profile": profile, "parallel": parallel, "scaling": scaling, "methods": methods,
     "interpolation": interpolation, "warm": warm, "settle": settle}[args.table](args)


if __name__ == "__main__":
    main()
