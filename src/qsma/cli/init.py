"""``qsma init deck.inp``: the configuration file equivalent to an Abaqus/CalculiX deck,
every setting spelled out and commented, for users who want full control.
``qsma init model.msh``: the configuration of a mesh file with physical groups, what the
mesh cannot give (materials, friction, supports, loads, probe) marked REQUIRED."""
from __future__ import annotations

from pathlib import Path
import sys

from ..errors import InputError
from .common import add_deck_arguments, is_deck, parse_levels_spec, read_deck_args

HELP = ("write the TOML configuration equivalent to an Abaqus/CalculiX deck (every "
        "setting spelled out, what the deck holds that qsma does not use as comments), "
        "or the configuration of a Gmsh mesh with what it cannot give marked REQUIRED")
#: Mesh files `qsma init` writes a skeleton for (a .inp is read as a deck).
MESH_SUFFIXES = (".msh",)


def add_arguments(p):
    p.add_argument("config", metavar="DECK", help="the Abaqus/CalculiX .inp deck, or a "
                   "Gmsh .msh mesh with a physical group per body")
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
    mesh = str(args.config).lower().endswith(MESH_SUFFIXES)
    if not is_deck(args.config) and not mesh:
        raise InputError(f"qsma init reads an Abaqus/CalculiX deck (.inp) or a Gmsh mesh "
                         f"(.msh), got {args.config!r}")
    out = Path(args.out) if args.out else Path(args.config).with_suffix(".toml")
    if out.exists() and not args.force:
        raise InputError(f"{out} exists; give another --out FILE or --force to replace it")
    if mesh:
        return _mesh_skeleton(args, out)
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


def _mesh_skeleton(args, out) -> int:
    """``qsma init model.msh``: the skeleton (:func:`qsma.deck.skeleton.mesh_toml`)."""
    from ..deck.skeleton import mesh_toml
    from ..output.folders import atomic_write
    given = [f"--{k.replace('_', '-')}" for k in ("tip_node", "tip_direction", "density",
                                                   "units", "levels", "mode")
             if getattr(args, k, None) is not None]
    if given:
        raise InputError(f"{', '.join(given)} apply to a deck; a mesh's configuration "
                         f"gets the probe, the levels and the materials in the TOML written")
    text = mesh_toml(args.config, out.parent)
    try:
        atomic_write(out, text)
    except OSError as exc:
        raise InputError(f"cannot write {out}: {exc.strerror}; choose another --out") from None
    print(f"wrote {out}: fill in the lines marked REQUIRED, then `qsma run {out}`")
    return 0
