"""Timing of the contact methods on load ramps of growing size.

Run from the repository root::

    .venv/bin/python benchmarks/bench_contact.py            # full table
    .venv/bin/python benchmarks/bench_contact.py --quick    # small sizes only
    .venv/bin/python benchmarks/bench_contact.py --robustness 1000   # random problems

Problem family (``chain_problem``): ``n`` pairs along a 2D interface
``x in [0, 1]``. Tangential stiffness: a bar of axial springs between
neighbouring pairs, clamped beyond the last pair, plus the graph Laplacian
of a dense exponential kernel (fills K without grounding the bar); normal
stiffness: a foundation plus the same kernel; a weak normal-tangential
coupling on each pair (0.2 % of the tangential stiffness). The normal
stiffness is scaled so that cond(K) = 1e6 at every size (the sandwich-2d
condensed interface has about 2e6 over its closed pairs, FIELD-NOTES).
Load ramp: a normal preload decreasing linearly along x (the far edge,
x > 0.77, is in tension and opens) and a tangential end load at x = 0
growing over 51 levels to 90 % of the friction capacity, so that slip
spreads from the loaded edge over about half of the closed pairs.

Every level of a ramp is warm-started from the previous one. Times are
the median over repeated ramps, per level; ``nit`` is the total of the
method's iterations over the ramp (block steps, Newton steps or sweeps).
"""
from __future__ import annotations

import argparse
import os
import statistics
import time
import warnings

# One BLAS thread: the matrices are small (<= 1000) and threads only add noise
# on a shared machine. Set OPENBLAS_NUM_THREADS yourself to override.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from qsma.contact import ContactProblem, solve  # noqa: E402
from qsma.errors import ContactConvergenceWarning  # noqa: E402

LEVELS = 51
TARGET_COND = 1e6


def chain_problem(n, mu=0.6, coupling=0.002):
    """Chain-like ill-conditioned 2D contact problem of ``n`` pairs and its load ramp.

    Returns ``(problem, ramp)`` with ``ramp`` of shape ``(LEVELS, n, 2)``.
    """
    x = np.linspace(0.0, 1.0, n)
    h = x[1] - x[0]
    bar = (np.diag(np.r_[1.0, np.full(n - 1, 2.0)]) - np.eye(n, k=1) - np.eye(n, k=-1)) / h
    kernel = np.exp(-np.abs(x[:, None] - x[None, :]) / 0.05)
    graph = kernel - np.eye(n)
    Kt = bar + np.diag(graph.sum(axis=1)) - graph      # bar + dense Laplacian (no grounding)
    Kn0 = np.eye(n) + kernel                           # foundation + dense coupling
    scale = TARGET_COND * np.linalg.eigvalsh(Kt)[0] / np.linalg.eigvalsh(Kn0)[-1]
    K = np.zeros((2 * n, 2 * n))
    K[0::2, 0::2], K[1::2, 1::2] = Kt, scale * Kn0
    K[0::2, 1::2] = K[1::2, 0::2] = coupling * np.diag(np.diag(Kt))   # weak t-n coupling
    preload = (1.0 - 1.3 * x) * h * scale              # far edge (x > 0.77) in tension
    ramp = np.zeros((LEVELS, n, 2))
    ramp[:, :, 1] = preload
    end_load = 0.9 * mu * np.sum(np.maximum(preload, 0.0))   # 90 % of the friction capacity
    ramp[:, 0, 0] = -np.linspace(0.0, end_load, LEVELS)
    return ContactProblem(K, mu), ramp


def run_ramp(problem, ramp, method, **options):
    """Solve every level with warm starts; ``(seconds, nit, max residual, failures, last)``."""
    state, nit, worst, failures = None, 0, 0.0, 0
    t0 = time.perf_counter()
    for lam_w in ramp:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ContactConvergenceWarning)
            result = solve(problem, lam_w, state, method=method, **options)
        state, nit = result.state, nit + result.nit
        worst, failures = max(worst, result.residual), failures + (not result.success)
    return time.perf_counter() - t0, nit, worst, failures, result


#: (label, method, options, largest size, repeats): the baselines are capped so
#: that the table finishes in minutes; their rows show what they reach.
CONFIGS = [
    ("basket", "basket", {}, 10 ** 9, 7),
    ("active_set", "active_set", {}, 10 ** 9, 7),
    ("basket gauss_seidel", "basket", {"coupling": "gauss_seidel", "maxiter": 2000,
                                       "fallback": False}, 130, 5),
    ("nodal_gs (200 sweeps)", "nodal_gs", {"maxiter": 200}, 130, 1),
    ("nodal_gs (2000 sweeps)", "nodal_gs", {"maxiter": 2000}, 50, 1),
]


def random_problem(rng, dim, mu_max, log_cond_max=3.0):
    """Random K = S R diag(logspace) R^T S (strong normal-tangential coupling), mu, loads."""
    n = int(rng.integers(1, 8))
    size = n * dim
    rotation, _ = np.linalg.qr(rng.standard_normal((size, size)))
    S = np.sqrt(rng.uniform(1.0, 10.0, size))
    spectrum = np.logspace(0, rng.uniform(0, log_cond_max), size)
    K = S[:, None] * ((rotation * spectrum) @ rotation.T) * S[None, :]
    mu = 0.0 if rng.random() < 0.2 else rng.uniform(0.05, mu_max)
    base = rng.standard_normal((n, dim)) * 10.0 ** rng.uniform(-3, 3)
    loads = [base + 0.5 * i * np.abs(base).max() * rng.standard_normal((n, dim))
             for i in range(4)]
    return ContactProblem(0.5 * (K + K.T), mu, dim=dim), loads


def robustness(samples, dim, mu_max, seed=0):
    """Failures and disagreements over random warm-started sequences of 4 levels."""
    methods = {"basket": {}, "active_set": {}, "nodal_gs": {"maxiter": 3000}}
    rng = np.random.default_rng(seed)
    fails, disagree, solves = dict.fromkeys(methods, 0), 0, 0
    for _ in range(samples):
        problem, loads = random_problem(rng, dim, mu_max)
        states = dict.fromkeys(methods)
        for lam_w in loads:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ContactConvergenceWarning)
                res = {m: solve(problem, lam_w, states[m], method=m, **o)
                       for m, o in methods.items()}
            solves += 1
            for m, r in res.items():
                fails[m] += not r.success
            ok = [r for r in res.values() if r.success]
            F = max(np.abs(lam_w).max(), *(np.abs(r.lam).max() for r in ok)) if ok else 1.0
            disagree += any(np.abs(r.lam - ok[0].lam).max() > 1e-6 * F for r in ok)
            good = res["basket"] if res["basket"].success else (ok[0] if ok else None)
            states = {m: (r.state if r.success else (good.state if good else None))
                      for m, r in res.items()}
    return solves, fails, disagree


def print_robustness(samples):
    print("| dim | mu | level solves | basket failed | active_set failed | "
          "nodal_gs (3000 sweeps) failed | levels where successful methods disagree |")
    print("| ---: | --- | ---: | ---: | ---: | ---: | ---: |")
    for dim, mu_max in ((2, 0.6), (2, 1.0), (3, 0.6)):
        solves, fails, disagree = robustness(samples, dim, mu_max)
        print(f"| {dim} | 0 or [0.05, {mu_max}] | {solves} | {fails['basket']} | "
              f"{fails['active_set']} | {fails['nodal_gs']} | {disagree} |")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="sizes 50 and 130 only")
    parser.add_argument("--robustness", type=int, metavar="N",
                        help="instead of timings: N random problems per row")
    args = parser.parse_args(argv)
    if args.robustness:
        print_robustness(args.robustness)
        return 0
    sizes = [25, 65] if args.quick else [25, 65, 250, 500]
    run_ramp(*chain_problem(sizes[0]), "basket")          # warm-up, not timed
    rows = []
    for n in sizes:
        problem, ramp = chain_problem(n)
        cond = np.linalg.cond(problem.K)
        for label, method, options, largest, repeats in CONFIGS:
            if 2 * n > largest:
                continue
            runs = [run_ramp(problem, ramp, method, **options) for _ in range(repeats)]
            seconds = statistics.median(r[0] for r in runs)
            _, nit, worst, failures, last = runs[0]
            rows.append((2 * n, cond, label, seconds, nit, worst, failures, last))
    print_table(rows)
    return 0


def print_table(rows):
    base = {r[0]: r[3] for r in rows if r[2] == "basket"}
    print(f"| unknowns | cond(K) | method | ramp total [ms] | per level [ms] | iterations "
          f"(51 levels) | max residual | failed levels | slipping/open at end | time / basket |")
    print("| ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for size, cond, label, seconds, nit, worst, failures, last in rows:
        print(f"| {size} | {cond:.1e} | {label} | {1e3 * seconds:.1f} | "
              f"{1e3 * seconds / LEVELS:.3f} | {nit} | {worst:.1e} | {failures} | "
              f"{last.n_slipping}/{last.n_open} | {seconds / base[size]:.1f} |")


if __name__ == "__main__":
    raise SystemExit(main())
