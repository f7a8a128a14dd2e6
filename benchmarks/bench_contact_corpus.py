"""Every contact method on the third-party corpus (Siconos test problems).

Usage: python benchmarks/bench_contact_corpus.py [--extra FILE ...] [--nodal-maxiter 2000]
                                                 [--repeat 3] [--methods ...] [--only-extra]

Problems: tests/data/contact/siconos/*.dat (see the README there) plus any
``--extra`` Siconos ``.dat`` files (e.g. ``fc2d_granularflowonwall_00667_00000.dat``
from a Siconos checkout; FCLIB global ``.hdf5`` files such as
``Spheres-i099-356-679.hdf5`` are condensed by ``read_fclib_global`` and need h5py).
Each is converted to ``ContactProblem(K = W^-1, mu)``,
``lam_w = -K q`` and solved from the reference state by every method. Printed per
method and problem: success, iterations, fallback, median time over ``--repeat``
runs, the residual (new), the force check, the legacy residual, and an independent
natural-map residual in the Delassus form (``u = W lam + q``, relative to
``max|lam|``). An *invalid success* is a success whose independent residual exceeds
1e-5 (tests/contact/test_contact_corpus.py, INDEPENDENT_TOL).
"""
import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from qsma.contact import METHODS, solve

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "contact"))
from external_problems import read_fclib_global, read_siconos_dat, stiffness_form  # noqa: E402
from test_contact_corpus import INDEPENDENT_TOL, MAX_ASYMMETRY, delassus_residual  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--extra", nargs="*", default=[])
    ap.add_argument("--nodal-maxiter", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--methods", nargs="*", default=None, help="default: every method")
    ap.add_argument("--only-extra", action="store_true", help="skip the files of the tests")
    args = ap.parse_args()
    methods = sorted(args.methods or METHODS)
    files = [] if args.only_extra else sorted(
        (ROOT / "tests" / "data" / "contact" / "siconos").glob("*.dat"))
    files += [Path(f) for f in args.extra]
    print("| problem | pairs | dim | cond(K) | method | success | nit | fallback | time [s] "
          "| residual | force check | legacy | independent |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    totals = {m: [0, 0, 0, 0.0] for m in methods}      # solved, invalid, fallbacks, time
    for path in files:
        read = read_fclib_global if path.suffix == ".hdf5" else read_siconos_dat
        delassus = read(path)
        problem, lam_w = stiffness_form(delassus, MAX_ASYMMETRY)
        cond = np.linalg.cond(problem.K)
        for method in methods:
            maxiter = args.nodal_maxiter if method == "nodal_gs" else None
            times = []
            for _ in range(args.repeat if method != "nodal_gs" else 1):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t = time.perf_counter()
                    r = solve(problem, lam_w, method=method, maxiter=maxiter)
                    times.append(time.perf_counter() - t)
            ind = delassus_residual(delassus, problem, r.lam)
            invalid = r.success and ind > INDEPENDENT_TOL
            tot = totals[method]
            tot[0] += r.success
            tot[1] += invalid
            tot[2] += r.fallback is not None
            tot[3] += statistics.median(times)
            print(f"| {path.stem} | {problem.n_pairs} | {problem.dim} | {cond:.1e} | {method} "
                  f"| {r.success}{' INVALID' if invalid else ''} | {r.nit} | {r.fallback or '-'} "
                  f"| {statistics.median(times):.3f} | {r.residual:.1e} | {r.residual_force:.1e} "
                  f"| {r.residual_legacy:.1e} | {ind:.1e} |", flush=True)
    print()
    print("| method | solved | invalid successes | fallbacks | total time [s] |")
    print("| --- | --- | --- | --- | --- |")
    for method, (ok, bad, fb, t) in totals.items():
        print(f"| {method} | {ok}/{len(files)} | {bad} | {fb} | {t:.2f} |")


if __name__ == "__main__":
    main()
