"""Options shared by the subcommands: where the model comes from."""
from __future__ import annotations

from ..errors import InputError
from ..options import RunOptions


def add_model_arguments(p):
    p.add_argument("config", nargs="?", help="TOML configuration file of the model and run")
    p.add_argument("--example", help="built-in benchmark model (e.g. sandwich-2d)")
    p.add_argument("--refine", type=int,
                   help="refinement level of the example mesh (default 1; --example only)")
    p.add_argument("--mu", type=float, help="friction coefficient (overrides the model)")


def load_model(args):
    """``(model, RunOptions)`` from ``--example`` or a configuration file."""
    from ..examples import EXAMPLES, check_refine
    if (args.config is None) == (args.example is None):
        raise InputError("give either a configuration file or --example NAME "
                         f"(examples: {sorted(EXAMPLES)})")
    if args.example is not None:
        if args.example not in EXAMPLES:
            raise InputError(f"unknown example {args.example!r}; valid: {sorted(EXAMPLES)}")
        refine = 1 if args.refine is None else args.refine
        check_refine(args.example, refine)          # before the mesh is made
        model = EXAMPLES[args.example](refine=refine, mu=args.mu)
        return model, RunOptions()
    if args.refine is not None:
        raise InputError("--refine applies to --example models only; refine the mesh files "
                         "of a configuration instead")
    from ..config import load_config
    cfg = load_config(args.config)
    model = cfg.model
    if args.mu is not None:
        model = model.with_mu(args.mu, what=f"--mu {args.mu:g}", fix=(
            "drop --mu and set mu in each [[interfaces]] table of the configuration"))
    return model, cfg.options
