"""Adversarial sweep: random contact problems, every method, invalid successes counted.

Usage: python benchmarks/bench_contact_adversarial.py [--problems 200] [--seed 0]
                                                      [--min-pairs 1] [--max-pairs 2000]
                                                      [--levels 4] [--nodal-max-pairs 30]
                                                      [--methods basket active_set ...]
                                                      [--seconds S] [--start 0]
                                                      [--list-failures]

Problem ``k`` of seed ``s`` is drawn from its own generator ``default_rng([s, k])``
(so a problem can be re-run alone, and tiers of sizes run in separate processes).
Each problem: dim 2 or 3; ``n`` pairs log-uniform in [min-pairs, max-pairs]; target
cond(K) log-uniform in [1, 1e10]; mu uniform in [0, 2]; initial gaps zero for half
of the problems, else uniform in +-1e-3 of the displacement scale; a warm-started
sequence of ``--levels`` welded forces ``lam_w = base + (k / levels) * swing`` (normal
part mostly compressive with some pairs pulled open, tangential part up to twice the
friction capacity, in random directions). The flexibility W is generated first
(for ``n * dim <= 900`` ``Q diag(geomspace(1, cond)) Q^T`` with a random orthogonal
Q; above, to keep the generation cheap, ``D^-1 (I + V V^T)^-1 D^-1`` with ``V`` of
rank 20 and a componentwise log-uniform diagonal ``D`` spanning ``sqrt(cond)``,
inverted by Woodbury), then ``K = W^-1``; each load is given as a free
displacement ``u0 = -W f`` and ``lam_w = -K u0`` (as Siconos' ``u = W r + q``).

A level is an *invalid success* when ``success`` is True but the independent check
fails: the natural map of ``d = W lam + u0`` (from the returned ``lam`` alone, no
solve with K and no cancellation), per pair in its own stiffness, relative to
``max|lam|``, above 1e-5 (as tests/contact/test_contact_corpus.py), or the force
check above ``FORCE_TOL``. The goal is zero. An exception other than
``InputError`` is counted as a crash (goal zero). ``nodal_gs`` (the baseline) runs
only on problems of at most ``--nodal-max-pairs`` pairs, capped at 2000 sweeps.
"""
import argparse
import signal
import time
import warnings

import numpy as np

from qsma.contact import FORCE_TOL, METHODS, ContactProblem, solve

INDEPENDENT_TOL = 1e-5


def random_problem(rng, max_pairs, min_pairs=1):
    dim = int(rng.choice([2, 3]))
    n = int(np.clip(round(np.exp(rng.uniform(np.log(min_pairs), np.log(max_pairs)))),
                    min_pairs, max_pairs))
    cond = 10 ** rng.uniform(0, 10)
    N = n * dim
    if N <= 900:
        Q, _ = np.linalg.qr(rng.normal(size=(N, N)))
        lam = np.geomspace(1.0, cond, N)
        K, W = (Q * lam) @ Q.T, (Q / lam) @ Q.T
    else:
        V = rng.normal(size=(N, 20)) / np.sqrt(N)
        D = np.exp(rng.uniform(0, 0.5 * np.log(cond), N))
        K = D[:, None] * (np.eye(N) + V @ V.T) * D[None, :]
        inner = V @ np.linalg.solve(np.eye(20) + V.T @ V, V.T)
        W = (np.eye(N) - inner) / D[:, None] / D[None, :]
    K, W = 0.5 * (K + K.T), 0.5 * (W + W.T)
    mu = rng.uniform(0, 2)
    scale = np.mean(np.diag(K))
    gap = None if rng.random() < 0.5 else rng.uniform(-1e-3, 1e-3, n) / scale
    return ContactProblem(K, mu, gap0=gap, dim=dim), W, cond


def load_sequence(rng, problem, W, levels):
    """``(lam_w, u0)`` per level: ``u0 = -W f`` for a force pattern ``f``, ``lam_w = -K u0``."""
    out = []
    for f in force_sequence(rng, problem, levels):
        u0 = -(W @ f.ravel())
        out.append((-(problem.K @ u0).reshape(f.shape), u0.reshape(f.shape)))
    return out


def force_sequence(rng, problem, levels):
    n, dim, mu = problem.n_pairs, problem.dim, problem.mu[0]
    base = np.zeros((n, dim))
    base[:, -1] = rng.uniform(-0.3, 1.0, n)
    swing = np.zeros((n, dim))
    angle = rng.uniform(0, 2 * np.pi, n)
    size = rng.uniform(0, 2.0) * max(mu, 0.1) * rng.uniform(0, 1, n)
    swing[:, 0] = size * np.cos(angle)
    if dim == 3:
        swing[:, 1] = size * np.sin(angle)
    swing[:, -1] = rng.normal(scale=0.2, size=n)
    return [base + (k / levels) * swing for k in range(1, levels + 1)]


def independent_residual(problem, W, u0, lam_w, lam, d_prev):
    """Natural map of ``d = W lam + u0`` per pair (own stiffness), less its floor, relative
    to ``max(max|lam|, sqrt(eps) max|lam_w|)``.

    The unit: the reaction, or ``sqrt(eps) = 1.5e-8`` times the load when the whole
    reaction is below that (every pair open: ``lam`` is then iteration and round-off
    noise, seen at 1.7e-14 of the load with nodal_gs on a 2-pair problem, and relative
    to itself it would read as order one). A reaction below 1.5e-8 of the load is
    judged at that resolution.

    The floor: at cond(K) ~ 1e10 the two representations K and W = K^-1 (both
    rounded) disagree; on this load they disagree by ``|W (K u0) - u0|``, the
    accuracy to which ``(K, lam_w)`` and ``(W, u0)`` are the same problem. Ten times
    that, in force units (``c_i``), is subtracted per pair.
    """
    d = (W @ lam.ravel()).reshape(lam.shape) + u0
    disagreement = np.abs(W @ (problem.K @ u0.ravel()) - u0.ravel()).reshape(lam.shape)
    c = np.einsum("kii->k", problem.diagonal_blocks) / problem.dim
    floor = 10 * c * disagreement.max(axis=1)
    P, Q = lam[:, -1], lam[:, :-1]
    w, dv = d[:, -1] + problem.gap0, d[:, :-1] - d_prev[:, :-1]
    r_n = np.abs(P - np.maximum(0.0, P - c * w))
    sigma = Q - c[:, None] * dv
    radius = problem.mu * np.maximum(P, 0.0)
    norm = np.linalg.norm(sigma, axis=1)
    proj = sigma * np.minimum(1.0, radius / np.maximum(norm, 1e-300))[:, None]
    r_t = np.linalg.norm(Q - proj, axis=1)
    excess = np.maximum(np.maximum(r_n, r_t) - floor, 0.0)
    unit = max(np.abs(lam).max(), np.sqrt(np.finfo(float).eps) * np.abs(lam_w).max(), 1e-300)
    return excess.max() / unit


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", type=int, default=200)
    ap.add_argument("--start", type=int, default=0, help="index of the first problem")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--min-pairs", type=int, default=1)
    ap.add_argument("--max-pairs", type=int, default=2000)
    ap.add_argument("--methods", nargs="*", default=None, help="default: every method")
    ap.add_argument("--levels", type=int, default=4)
    ap.add_argument("--nodal-max-pairs", type=int, default=30)
    ap.add_argument("--list-failures", action="store_true",
                    help="print each failed level (problem, method, level, cond, mu), e.g. "
                         "to compare two versions problem by problem")
    ap.add_argument("--seconds", type=float, default=None,
                    help="stop drawing new problems after this many seconds (or on SIGTERM)")
    args = ap.parse_args()
    methods = sorted(args.methods or METHODS)
    keys = ("levels", "solved", "failed", "invalid", "crash", "fallback", "nit", "time")
    stats = {m: dict.fromkeys(keys, 0) for m in methods}
    by_cond = {m: {} for m in methods}
    level_times = {m: [] for m in methods}
    t_start = time.perf_counter()
    done = 0
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(True))   # finish the problem, report
    for k in range(args.start, args.start + args.problems):
        if stop or (args.seconds is not None and time.perf_counter() - t_start > args.seconds):
            break
        done += 1
        rng = np.random.default_rng([args.seed, k])
        problem, W, cond = random_problem(rng, args.max_pairs, args.min_pairs)
        loads = load_sequence(rng, problem, W, args.levels)
        for method in methods:
            if method == "nodal_gs" and problem.n_pairs > args.nodal_max_pairs:
                continue
            s, state = stats[method], None
            for lam_w, u0 in loads:
                s["levels"] += 1
                t = time.perf_counter()
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        r = solve(problem, lam_w, state, method=method,
                                  maxiter=2000 if method == "nodal_gs" else None)
                except Exception as err:                        # noqa: BLE001 - counted
                    s["crash"] += 1
                    print(f"CRASH problem {k} {method}: {type(err).__name__}: {err}")
                    break
                s["time"] += time.perf_counter() - t
                level_times[method].append(time.perf_counter() - t)
                s["nit"] += r.nit
                s["fallback"] += r.fallback is not None
                d_prev = np.zeros_like(lam_w) if state is None else state.d
                if r.success:
                    bad = (r.residual_force > FORCE_TOL or independent_residual(
                        problem, W, u0, lam_w, r.lam, d_prev) > INDEPENDENT_TOL)
                    s["solved"] += 1
                    s["invalid"] += bad
                    if bad:
                        print(f"INVALID problem {k} {method}: n={problem.n_pairs} "
                              f"dim={problem.dim} cond={cond:.1e} mu={problem.mu[0]:.2f}")
                    state = r.state
                else:
                    s["failed"] += 1
                    if args.list_failures:
                        print(f"FAILED problem {k} {method}: level {s['levels']} "
                              f"n={problem.n_pairs} dim={problem.dim} cond={cond:.1e} "
                              f"mu={problem.mu[0]:.2f}: {r.message[:80]}")
                    decade = int(np.log10(cond))
                    by_cond[method][decade] = by_cond[method].get(decade, 0) + 1
                    break                        # a ramp stops at its first failure
        if done % 20 == 0:
            print(f"... {done} problems, {time.perf_counter() - t_start:.0f} s", flush=True)
    print(f"\n{done} problems (indices {args.start}-{args.start + done - 1}, seed {args.seed}, "
          f"pairs {args.min_pairs}-{args.max_pairs}, "
          f"{args.levels} levels), {time.perf_counter() - t_start:.0f} s\n")
    print("| method | levels | solved | failed | invalid successes | crashes | fallbacks "
          "| iterations | time [s] | median / max level [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for m, s in stats.items():
        times = level_times[m] or [0.0]
        print(f"| {m} | {s['levels']} | {s['solved']} | {s['failed']} | {s['invalid']} "
              f"| {s['crash']} | {s['fallback']} | {s['nit']} | {s['time']:.1f} "
              f"| {np.median(times):.3f} / {max(times):.2f} |")
    print("\nfailures by decade of cond(K):", {m: dict(sorted(v.items()))
                                                for m, v in by_cond.items()})


if __name__ == "__main__":
    main()
