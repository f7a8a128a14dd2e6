"""Options shared by the subcommands: where the model comes from, the run options with a
flag, the levels."""
from __future__ import annotations

from ..errors import InputError
from ..analysis.options import RunOptions
from ..units import UNIT_SYSTEMS

#: RunOptions fields that have a command-line flag of the same name.
CLI_OPTIONS = ("mode", "method", "tol", "maxiter", "dissipation", "direct_loop",
               "continue_on_failure", "loop_workers", "loop_scheduler", "max_cycles")


def add_model_arguments(p):
    p.add_argument("config", nargs="?", help="TOML configuration file of the model and run, "
                   "or an Abaqus/CalculiX deck (.inp, docs/mesh-io.md 'Running a deck')")
    p.add_argument("--example", help="built-in benchmark model (e.g. sandwich-2d)")
    p.add_argument("--refine", type=int,
                   help="refinement level of the example mesh (default 1; --example only)")
    p.add_argument("--mu", type=float, help="friction coefficient (overrides the model)")
    add_deck_arguments(p)


def add_deck_arguments(p):
    p.add_argument("--tip-node", type=int, metavar="ID",
                   help="deck only: the node (its id in the deck) whose displacement is the "
                        "probe (default: the node of largest displacement in the mode)")
    p.add_argument("--tip-direction", metavar="X,Y[,Z]",
                   help="deck only: direction of the probe (default: the axis of the probe "
                        "node's largest modal displacement)")
    p.add_argument("--density", type=float, metavar="RHO",
                   help="deck only: density of the materials that give no *DENSITY, in the "
                        "deck's units (e.g. 7.85e-9 t/mm^3 or 7850 kg/m^3 for steel)")
    p.add_argument("--units", choices=sorted(UNIT_SYSTEMS),
                   help="deck only: the deck's unit system (default: the one its materials' "
                        "E and rho fit, else SI)")


def is_deck(path) -> bool:
    return path is not None and str(path).lower().endswith(".inp")


def read_deck_args(args, levels=None):
    """The :class:`qsma.deck.Deck` of ``args.config`` with the probe options."""
    from ..deck import read_deck
    direction = None
    if args.tip_direction is not None:
        try:
            direction = [float(v) for v in args.tip_direction.split(",")]
        except ValueError:
            raise InputError(f"--tip-direction {args.tip_direction!r}: give numbers "
                             f"separated by commas, e.g. 0,0,1") from None
    return read_deck(args.config, mode=getattr(args, "mode", None) or 0,
                     tip_node=args.tip_node, tip_direction=direction, levels=levels,
                     density=args.density, units=args.units)


def deck_refusal(deck) -> InputError:
    """The error of a deck that cannot be run as it is: every refusal, and the way out."""
    lines = "\n".join(f"  {n}" for n in deck.refusals)
    return InputError(f"{deck.source} cannot be run as it is: {len(deck.refusals)} thing(s) "
                      f"in it would change the answer and qsma does not model them:\n{lines}\n"
                      f"Change the deck, or write the equivalent configuration with `qsma "
                      f"init {deck.source}` (they become comments there), decide, and run "
                      f"that file")


def _load_deck(args):
    """``(model, RunOptions)`` of a deck; its notes as warnings."""
    import warnings
    from ..analysis.config import parse_config
    from ..errors import QSMAWarning
    deck = read_deck_args(args)
    if deck.refusals:
        raise deck_refusal(deck)
    for n in deck.notes:
        warnings.warn(str(n), QSMAWarning, stacklevel=2)
    cfg = parse_config(deck.config, base=deck.source.parent, where=str(deck.source))
    return cfg


def add_amplitude_argument(p):
    """``--amplitude``: the measure the figures draw frequency and damping against,
    the same for a run and a study (:data:`qsma.output.plots.AMPLITUDES`)."""
    p.add_argument("--amplitude", choices=("tip", "velocity", "q"), default="tip",
                   help="amplitude measure of the figures: peak tip deflection (tip, "
                        "the default), peak tip velocity or peak modal amplitude q")


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
    if is_deck(args.config):
        cfg = _load_deck(args)
    else:
        if any(getattr(args, k, None) is not None for k in ("tip_node", "tip_direction",
                                                              "density", "units")):
            raise InputError("--tip-node, --tip-direction, --density and --units apply to "
                             ".inp decks; a configuration file gives the probe in its [tip] "
                             "table, the density per body and its unit system as `units` "
                             "at its top")
        from ..analysis.config import load_config
        cfg = load_config(args.config)
    model = cfg.model
    if args.mu is not None:
        model = model.with_mu(args.mu, what=f"--mu {args.mu:g}", fix=(
            "drop --mu and set mu in each [[interfaces]] table of the configuration"))
    return model, cfg.options


def parse_levels_spec(spec: str):
    """``KIND:log|linear:START:STOP:N`` or ``KIND:list:V1,V2,...`` -> Levels."""
    from ..analysis.config import parse_levels
    parts = spec.split(":")
    try:
        if len(parts) == 3 and parts[1] == "list":
            table = dict(kind=parts[0], spacing="list",
                         values=[float(v) for v in parts[2].split(",")])
        elif len(parts) == 5:
            table = dict(kind=parts[0], spacing=parts[1], start=float(parts[2]),
                         stop=float(parts[3]), n=int(parts[4]))
        else:
            raise ValueError
    except ValueError:
        raise InputError(f"--levels {spec!r}: expected KIND:log|linear:START:STOP:N or "
                         f"KIND:list:V1,V2,... (e.g. tip:log:1e-6:1e-3:51)") from None
    return parse_levels(table, where="--levels")
