"""``qsma init deck.inp``: the configuration file equivalent to an Abaqus/CalculiX deck,
every setting spelled out and commented, for users who want full control."""
from __future__ import annotations

from pathlib import Path
import sys

from ..errors import InputError
from .common import add_deck_arguments, is_deck, parse_levels_spec, read_deck_args

HELP = ("write the TOML configuration equivalent to an Abaqus/CalculiX deck (every "
        "setting spelled out, what the deck holds that qsma does not use as comments)")


def add_arguments(p):
    p.add_argument("config", metavar="DECK", help="the Abaqus/CalculiX .inp deck")
    p.add_argument("-o", "--out", metavar="FILE",
                   help="the TOML file written (default: DECK with the suffix .toml)")
    p.add_argument("--force", action="store_true", help="replace FILE if it exists")
    p.add_argument("--mode", type=int, help="the mode loaded (default 0); also chooses the "
                                             "default probe")
    p.add_argument("--levels", metavar="SPEC", help="load levels (as qsma run --levels); "
                   "default: the probe's deflection from 1e-6 to 1e-2 of the model's size")
    add_deck_arguments(p)


def execute(args) -> int:
    from ..deck import deck_toml
    from ..output.folders import atomic_write
    if not is_deck(args.config):
        raise InputError(f"qsma init reads an Abaqus/CalculiX deck (.inp), got "
                         f"{args.config!r}")
    out = Path(args.out) if args.out else Path(args.config).with_suffix(".toml")
    if out.exists() and not args.force:
        raise InputError(f"{out} exists; give another --out FILE or --force to replace it")
    levels = parse_levels_spec(args.levels) if args.levels else None
    deck = read_deck_args(args, levels=levels)
    try:
        atomic_write(out, deck_toml(deck, out.parent))
    except OSError as exc:
        raise InputError(f"cannot write {out}: {exc.strerror}; choose another --out") from None
    for n in deck.notes:
        tag = "not modelled (the file runs without it)" if n.refuses else "note"
        print(f"qsma: {tag}: {n}", file=sys.stderr)
    print(f"wrote {out}")
    return 0
