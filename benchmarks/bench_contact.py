"""Timing of the contact methods on load ramps of growing size.

Run from the repository root::

    .venv/bin/python benchmarks/bench_contact.py            # full table
    .venv/bin/python benchmarks/bench_contact.py --quick    # small sizes only

Problem family (``chain_problem``): ``n`` pairs along a 2D interface
``x in [0, 1]``. Tangential stiffness: a bar of axial springs between
neighbouring pairs, clamped beyond the last pair, plus a dense smooth
coupling (exponential kernel) that fills K; normal stiffness: a stiff
foundation with the same kind of dense coupling, plus a weak
normal-tangential coupling. The normal stiffness is scaled so that
cond(K) is about 1e6 at every size (the sandwich-2d condensed interface
has about 2e6 over its closed pairs, FIELD-NOTES). Load ramp: a normal
preload decreasing linearly along x (the far edge is in tension and
opens), and a tangential end load at x = 0 growing over 51 levels, so that
slip spreads from the loaded edge over about half of the pairs.

Every level of a ramp is warm-started from the previous one. Times are
the median over repeated ramps, per level; ``nit`` is the total of the
method's iterations over the ramp (block steps, Newton steps or sweeps).
"""
from __future__ import annotations

import argparse
import statistics
import time
import warnings

import numpy as np

from qsma.contact import ContactProblem, solve
from qsma.errors import ContactConvergenceWarning

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
                                       "fallback": False}, 130, 1),
    ("nodal_gs (200 sweeps)", "nodal_gs", {"maxiter": 200}, 130, 1),
]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="sizes 50 and 130 only")
    args = parser.parse_args(argv)
    sizes = [25, 65] if args.quick else [25, 65, 250, 500]
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
