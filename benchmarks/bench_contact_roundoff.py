"""Does the round-off allowance of the residual matter on our own problems?

Usage: python benchmarks/bench_contact_roundoff.py [--refine 1] [--factors 0 0.5 1 8]

Solves the sandwich-2d ramp (the reduced problem, preload state and welded forces
of one ``qsma.run``, every level warm-started, no fallback) with
``qsma.contact.residual.ROUNDOFF`` set to each factor, and prints the failed
levels and total iterations of ``basket`` and ``active_set``. Measured (refine 1,
51 levels, cond(K) = 8.6e6): 0 failed levels and 66 iterations for every factor,
including 0 - the allowance guards the cancellation cases (a load far above the
reaction), it is not needed to converge on the sandwich.
"""
import argparse
import warnings

import qsma
from qsma.contact import ContactProblem, solve
from qsma.contact import residual as residual_module
from qsma.examples import sandwich_2d


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, default=1)
    ap.add_argument("--factors", type=float, nargs="+", default=[0.0, 0.5, 1.0, 8.0])
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    res = qsma.run(sandwich_2d(args.refine))
    problem = ContactProblem(res.reduced.K, res.model_info["mu"])
    loads = [res.reduced.welded_contact_force([1.0, a]) for a in res.alpha]
    default = residual_module.ROUNDOFF
    try:
        for factor in args.factors:
            residual_module.ROUNDOFF = factor
            for method in ("basket", "active_set"):
                state, failed, nit = res.preload.state, 0, 0
                for lam_w in loads:
                    r = solve(problem, lam_w, state, method=method, fallback=False)
                    failed, nit, state = failed + (not r.success), nit + r.nit, r.state
                print(f"ROUNDOFF={factor:g} {method}: failed levels {failed}/{len(loads)}, "
                      f"iterations {nit}")
    finally:
        residual_module.ROUNDOFF = default


if __name__ == "__main__":
    main()
