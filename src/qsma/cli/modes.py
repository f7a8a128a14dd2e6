"""``qsma modes``: natural frequencies of the assembly with interface pairs tied; and
``qsma run --modes 0,1,2`` (:func:`execute_modes`): one backbone per mode."""
from __future__ import annotations

import json
import sys

import numpy as np

from ..errors import InputError
from .common import CLI_OPTIONS, add_model_arguments, load_model, parse_levels_spec

HELP = "natural frequencies and mode shapes with interface pairs tied"


def add_arguments(p):
    add_model_arguments(p)
    p.add_argument("--tie", default="all", choices=["all", "none", "preload"],
                   help="pairs tied: all, none, or those closed after the preload")
    p.add_argument("-n", "--n-modes", type=int, default=6, help="number of modes")
    p.add_argument("--json", action="store_true", help='print {"f_hz": [...]} as JSON')
    p.add_argument("--out", metavar="DIR",
                   help="also write DIR/modes.vtu (mode shapes mode_00, ...) and "
                        "DIR/modes.json (frequencies)")


def execute(args) -> int:
    from contextlib import nullcontext
    from ..output.folders import RunFolder
    model, _ = load_model(args)
    if args.n_modes < 1:
        raise InputError(f"--n-modes must be >= 1, got {args.n_modes}")
    with RunFolder(args.out, kind="modes") if args.out else nullcontext() as folder:
        return _modes(args, model, folder)      # the folder taken before computing


def _modes(args, model, folder) -> int:
    from ..fe import assemble_body
    from ..modal import linear_modes
    from ..model import make_pairing
    pairing = make_pairing(model)
    assembled = [assemble_body(b) for b in model.bodies]
    if args.tie == "all":
        tied = np.ones(pairing.n_pairs, bool)
    elif args.tie == "none":
        tied = np.zeros(pairing.n_pairs, bool)
    else:
        tied = _closed_after_preload(model, assembled, pairing)
    modes = linear_modes(model, assembled, pairing, tied=tied, n_modes=args.n_modes)
    if folder is not None:
        _write(model, modes, args.tie, int(tied.sum()), folder)
    if args.json:
        print(json.dumps({"f_hz": modes.f_hz.tolist(), "tied_pairs": int(tied.sum())}))
    else:
        print(f"{model.name}: {int(tied.sum())} of {pairing.n_pairs} pairs tied")
        for k, f in enumerate(modes.f_hz):
            print(f"  mode {k}: {f:12.4f} Hz")
    return 0


def _closed_after_preload(model, assembled, pairing):
    from ..analysis import preload
    _, _, pre = preload(model, assembled, pairing)
    from ..contact import OPEN
    return pre.status != OPEN


def _write(model, modes, tie, n_tied, folder):
    """modes.vtu and modes.json into the result folder ``folder`` (an entered
    :class:`qsma.output.folders.RunFolder`), then swapped into place."""
    from ..output.files import atomic_write
    from ..study.modes import MODES_JSON, MODES_VTU, write_modes_vtu
    write_modes_vtu(model, modes, folder.staging / MODES_VTU)
    atomic_write(folder.staging / MODES_JSON, json.dumps(dict(
        model=model.name, tie=tie, tied_pairs=n_tied, f_hz=modes.f_hz.tolist()),
        indent=1) + "\n")
    folder.commit()


def execute_modes(args) -> int:
    from ..study.modes import parse_modes, run_modes
    if args.mode is not None:
        raise InputError("give either --mode K or --modes K1,K2,... (not both)")
    modes = parse_modes(args.modes)
    model, options = load_model(args)
    options = options.replace(**{key: getattr(args, key) for key in CLI_OPTIONS
                                 if key != "mode"},
                              levels=None if args.levels is None
                              else parse_levels_spec(args.levels))
    out = run_modes(model, modes, options, out=args.out, plots=not args.no_plots,
                    vtu=not args.no_vtu)
    for e in out.summary:
        line = (f"mode {e['mode']}: f0 = {e['f0_hz']:.3f} Hz, {e['message']}"
                if e["f0_hz"] is not None else f"mode {e['mode']}: {e['message']}")
        if e["success"]:
            if not args.quiet:
                print(line)
        else:
            print(f"qsma: warning: {line}", file=sys.stderr)
    if not args.quiet:
        print("results: " + ", ".join(str(p) for p in out.paths.values()))
    return 0 if out.success else 1
