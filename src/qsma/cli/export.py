"""``qsma export --calculix OUT.inp MODEL``: the model as a runnable CalculiX 2.20 deck
of the same QSMA (:func:`qsma.deck.export_calculix`), to check a result of qsma in
another code."""
from __future__ import annotations

from pathlib import Path

from ..errors import InputError
from .common import add_model_arguments, load_model, parse_levels_spec

HELP = ("write the model as a CalculiX deck of the same QSMA (preload, tied modes, cyclic "
        "modal load), to check qsma's results in CalculiX")


def add_arguments(p):
    p.add_argument("--calculix", metavar="OUT.inp", required=True,
                   help="the CalculiX deck written (with --tied also OUT-tied.inp)")
    add_model_arguments(p)
    p.add_argument("--mode", type=int, default=0, help="the mode loaded (default 0)")
    p.add_argument("--tied", action="store_true",
                   help="also write OUT-tied.inp: the pairs qsma's preload closes tied "
                        "(*EQUATION), a linear frequency step: qsma's tied modes in "
                        "CalculiX (runs qsma's preload)")
    p.add_argument("--amplitudes", metavar="SPEC",
                   help="cyclic steps of the modal load at these levels, as qsma run "
                        "--levels (e.g. tip:list:1e-5,1e-4); runs qsma's preload and mode")
    p.add_argument("--steps", type=int, default=20,
                   help="increments per branch of the cyclic steps (default 20)")
    p.add_argument("--cycles", type=int, default=2, metavar="N",
                   help="cycles +A -> -A -> +A per amplitude after the ramp to +A "
                        "(default 2, at least 2): compare the last with qsma's stabilised "
                        "loop; give as many as qsma's loop took (results.json loop_cycles)")
    p.add_argument("--penalty", type=float, metavar="K",
                   help="slope (Pa/m) of the penalty standing for qsma's hard contact "
                        "and rigid stick (default 1e4 E / h of each interface)")
    p.add_argument("--force", action="store_true", help="replace OUT.inp if it exists")


def execute(args) -> int:
    from dataclasses import replace
    from ..deck import export_calculix
    out = Path(args.calculix)
    if out.suffix.lower() != ".inp":
        raise InputError(f"--calculix {args.calculix!r}: give a file ending in .inp")
    if out.exists() and not args.force:
        raise InputError(f"{out} exists; give another file or --force to replace it")
    model, options = load_model(args)
    options = replace(options, mode=args.mode)
    amplitudes = parse_levels_spec(args.amplitudes) if args.amplitudes else None
    deck = export_calculix(model, out, options=options, amplitudes=amplitudes,
                           penalty=args.penalty, steps=args.steps, cycles=args.cycles,
                           tied=args.tied)
    print(f"wrote {deck.path}" + (f" and {deck.tied_path}" if deck.tied_path else ""))
    print(f"run: ccx -i {out.with_suffix('')}")
    return 0
