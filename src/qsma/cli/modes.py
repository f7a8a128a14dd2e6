"""``qsma modes``: natural frequencies of the assembly with interface pairs tied."""
from __future__ import annotations

import json

import numpy as np

from ..errors import InputError
from .common import add_model_arguments, load_model

HELP = "natural frequencies and mode shapes with interface pairs tied"


def add_arguments(p):
    add_model_arguments(p)
    p.add_argument("--tie", default="all", choices=["all", "none", "preload"],
                   help="pairs tied: all, none, or those closed after the preload")
    p.add_argument("-n", "--n-modes", type=int, default=6, help="number of modes")
    p.add_argument("--json", action="store_true", help='print {"f_hz": [...]} as JSON')


def execute(args) -> int:
    from ..fe import assemble_body
    from ..modal import linear_modes
    from ..model import make_pairing
    model, _ = load_model(args)
    if args.n_modes < 1:
        raise InputError(f"--n-modes must be >= 1, got {args.n_modes}")
    pairing = make_pairing(model)
    assembled = [assemble_body(b) for b in model.bodies]
    if args.tie == "all":
        tied = np.ones(pairing.n_pairs, bool)
    elif args.tie == "none":
        tied = np.zeros(pairing.n_pairs, bool)
    else:
        tied = _closed_after_preload(model, assembled, pairing)
    modes = linear_modes(model, assembled, pairing, tied=tied, n_modes=args.n_modes)
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
