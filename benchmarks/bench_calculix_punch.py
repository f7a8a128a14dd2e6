"""The preload of CalculiX's punch decks in qsma and in ccx 2.20: a cylindrical punch on a
block, apart from it by up to 0.30 of an element away from the line where they touch.

    python benchmarks/bench_calculix_punch.py FOLDER [--deck punch1]

FOLDER holds the deck (the ``test/`` folder of the CalculiX source distribution). ccx
solves the deck twice, small-displacement (its ``NLGEOM`` dropped, as qsma's preload
is): as it is (``ADJUST=`` moves slave nodes near the master onto it) and without
``ADJUST=`` (the gaps as meshed). qsma's preload (``qsma run``'s model of the deck)
gives its displacements, with the deck's ``ADJUST=`` distance (the interface's
``adjust``: the gaps within it zero) and with the gaps as meshed. The table: the force ``K u`` that each
solution puts on the block's contact face, summed over each row of nodes across the
line of contact (x), and the largest displacement.
"""
from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
import re
import sys
import tempfile
import warnings

import numpy as np

import qsma
from qsma.analysis.config import parse_config
from qsma.analysis.levels import Levels
from qsma.deck import read_deck
from qsma.deck.calculix_output import displacements, run_calculix
from qsma.fe import assemble_body
from qsma.mesh.io import read_assembly


def ccx_displacements(deck: Path, folder: Path, adjust: bool) -> np.ndarray:
    """Nodal displacements (file node order) of ccx on ``deck`` without NLGEOM."""
    text = re.sub(r"(?im)^\*STEP\s*,\s*NLGEOM", "*STEP", deck.read_text())
    if not adjust:
        text = re.sub(r"(?i),\s*ADJUST\s*=\s*[^,\n]*", "", text)
    path = folder / f"{deck.stem}_{'adjust' if adjust else 'meshed'}.inp"
    path.write_text(text)
    return displacements(run_calculix(path), len(read_assembly(deck).file_mesh.points))[-1][1]


def body_nodes(deck: Path, k: int) -> np.ndarray:
    """File node indices of the deck's ``k``-th body (connected part), in its order."""
    fm = read_assembly(deck).file_mesh
    cells = read_assembly(deck).components()[k]
    offsets = np.concatenate([[0], np.cumsum([len(c) for _, _, c, _ in fm.blocks])])
    used = np.zeros(len(fm.points), dtype=bool)
    for b, (_, _, conn, _) in enumerate(fm.blocks):
        mine = np.isin(np.arange(offsets[b], offsets[b + 1]), cells)
        used[conn[mine].ravel()] = True
    return np.flatnonzero(used)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--deck", default="punch1")
    args = ap.parse_args(argv)
    deck = args.folder / f"{args.deck}.inp"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = parse_config(read_deck(deck, density=7.85e-9).config, base=deck.parent).model
        meshed = dataclasses.replace(model, interface=dataclasses.replace(
            model.interface, adjust=None))
        runs = {name: qsma.run(m, levels=Levels("alpha", (1e-3,)), method="basket")
                for name, m in (("qsma, ADJUST", model), ("qsma, as meshed", meshed))
                if name == "qsma, as meshed" or model.interface.adjust is not None}
    res = next(iter(runs.values()))
    itf = model.interface
    k = model.body_index(itf.body1)                       # the master: the block
    block = model.bodies[k]
    a = assemble_body(block)
    with tempfile.TemporaryDirectory() as tmp:
        u_all = {"ccx, ADJUST": ccx_displacements(deck, Path(tmp), True),
                 "ccx, as meshed": ccx_displacements(deck, Path(tmp), False)}
    nodes = body_nodes(deck, k)
    u = {name: np.asarray(r.fields(None)[k]).reshape(-1, 3) for name, r in runs.items()}
    u.update({name: v[nodes, :3] for name, v in u_all.items()})
    face = block.mesh.nodes(itf.set1)
    x = np.round(block.mesh.points[face, 0], 6)
    for name, r in runs.items():
        pre = r.preload
        print(f"{args.deck}: {name} preload {len(pre.status) - pre.n_open} of "
              f"{len(pre.status)} pairs closed, largest initial gap {r.pairing.gap.max():.4g}")
    print(f"{'x':>8s} " + " ".join(f"{n:>15s}" for n in u))
    force = {n: (a.K @ v.ravel()).reshape(-1, 3)[face, 2] for n, v in u.items()}
    for xv in np.unique(x):
        print(f"{xv:8.4f} " + " ".join(f"{f[x == xv].sum():15.4f}" for f in force.values()))
    print(f"{'sum':>8s} " + " ".join(f"{f.sum():15.4f}" for f in force.values()))
    print(f"{'max |u|':>8s} " + " ".join(f"{np.abs(v).max():15.4e}" for v in u.values()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
