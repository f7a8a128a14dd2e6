"""``qsma fit``: parameters of the model adjusted to measured frequency and damping."""
from __future__ import annotations

from ..errors import InputError
from .common import add_model_arguments, load_model, parse_levels_spec

HELP = ("fit parameters (friction coefficient, preload scale, materials) to measured "
        "frequency and damping versus amplitude")


def add_arguments(p):
    add_model_arguments(p)
    p.add_argument("--measured", required=True, metavar="CSV",
                   help="measured data: amplitude column tip_m|tip_mm|tip_um|q, then "
                        "f_hz and/or zeta (docs/studies.md)")
    p.add_argument("--params", required=True, metavar="NAMES",
                   help="parameters to fit, e.g. mu or mu,preload (also E, nu, rho, "
                        "E:BODY)")
    p.add_argument("--out", required=True, help="folder for fit.json, fit.csv, fit.png "
                                                "and the fitted run (best/)")
    p.add_argument("--start", metavar="NAME=V,...", help="start values (default: the "
                                                         "model's; preload 1)")
    p.add_argument("--bounds", metavar="NAME=LOW:HIGH,...", help="bounds of the parameters")
    p.add_argument("--sigma-f", type=float, default=1e-3,
                   help="expected relative scatter of the measured frequency (weight; "
                        "default 1e-3)")
    p.add_argument("--sigma-zeta", type=float, default=0.1,
                   help="expected relative scatter of the measured damping (weight; "
                        "default 0.1)")
    p.add_argument("--levels", metavar="SPEC", help="load levels of each evaluation (as "
                                                    "qsma run --levels; default: spanning "
                                                    "the measured tip amplitudes)")
    p.add_argument("--mode", type=int, help="mode index")
    p.add_argument("--max-evaluations", type=int, default=60,
                   help="optimiser evaluations (default 60)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")


def execute(args) -> int:
    import sys
    from ..study.fit import fit, parse_assignments
    if args.max_evaluations < 1:
        raise InputError(f"--max-evaluations must be >= 1, got {args.max_evaluations}")
    model, options = load_model(args)
    options = options.replace(mode=args.mode, levels=None if args.levels is None
                              else parse_levels_spec(args.levels))
    names = tuple(n.strip() for n in args.params.split(",") if n.strip())
    fr = fit(model, args.measured, names, options,
             start=parse_assignments(args.start, "start"),
             bounds=parse_assignments(args.bounds, "bounds"), sigma_f=args.sigma_f,
             sigma_zeta=args.sigma_zeta, max_evaluations=args.max_evaluations,
             out=args.out)
    if not args.quiet or not fr.success:
        for k in fr.names:
            print(f"{k} = {fr.values[k]:.6g} +- {fr.sigma[k]:.3g} (start {fr.start[k]:g})")
        print(f"{fr.nfev} runs; residual sigma {fr.residual_sigma:.3g} (in units of the "
              f"given scatter)")
        print("results: " + ", ".join(str(p) for p in fr.paths.values()))
    if not fr.success:
        print(f"qsma: warning: {fr.message}", file=sys.stderr)
        return 1
    return 0
