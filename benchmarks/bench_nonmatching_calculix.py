"""How far qsma gets with the CalculiX test decks that hold a ``*CONTACT PAIR``.

    python benchmarks/bench_nonmatching_calculix.py FOLDER [--all-types]

FOLDER holds ``.inp`` decks (CalculiX's ``test/`` folder of its source distribution).
Each deck with a ``*CONTACT PAIR`` goes through the stages below, and the first stage
that fails is its outcome (one line per deck, then the counts per outcome):

1. read       ``qsma.model.io.read_assembly``
2. C3D8       the cells are hexahedra (8-node bricks; other cell types are counted
              apart unless --all-types)
3. bodies     the connected parts of the mesh are the bodies; each contact pair's
              surfaces lie on two different bodies
4. model      bodies (steel; clamps from the homogeneous ``*BOUNDARY`` rows), one
              interface per contact pair (its ``*FRICTION`` mu, else 0.3)
5. pairing    every interface coupled (node-to-node or mortar)
6. modes      the tied assembly's lowest mode
7. run        a QSMA run needs a bolt preload (pressure) and a tip probe, which a
              CalculiX deck expresses as ``*CLOAD`` / ``*DLOAD`` steps that qsma does
              not translate: every deck that reaches this stage stops here, named
              "needs preload and probe".

The timings are not the point: this is a coverage count.
"""
from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
import re
import sys
import warnings

import numpy as np

from qsma.errors import QSMAError
from qsma.fe import assemble_body
from qsma.modal import linear_modes
from qsma.model import Body, Clamp, Interface, Material, Model
from qsma.model.io import read_assembly
from qsma.multibody import multi_pairing

STEEL = Material(210e9, 0.3, 7800.0)


def _first_line(exc) -> str:
    text = str(exc).splitlines()[0]
    return re.sub(r"^\S+\.inp(, line \d+)?: ", "", text)[:150]


def survey(path: Path, all_types=False):
    """``(stage reached, detail)`` of one deck."""
    try:
        asm = read_assembly(path)
    except QSMAError as exc:
        return "read failed", _first_line(exc)
    if asm.cell_type != "hexahedron" and not all_types:
        return "not C3D8", asm.cell_type
    try:
        meshes = asm.component_meshes()
    except QSMAError as exc:
        return "bodies failed", _first_line(exc)
    names = [f"body{k + 1}" for k in range(len(meshes))]
    interfaces, seen = [], set()
    for pair in asm.contact_pairs:
        owners = []
        for surf in (pair.slave, pair.master):
            found = [k for k, m in enumerate(meshes) if surf in m.facet_sets
                     and len(m.facet_sets[surf])]
            if not found:
                nodes = [len(m.node_sets.get(surf, ())) for m in meshes]
                if any(nodes):
                    return "bodies failed", (f"node surface {surf!r} of {max(nodes)} "
                                             f"node(s) spans no element face (an interface "
                                             f"needs faces)")
                return "bodies failed", f"surface {surf!r} holds no facet of any body"
            owners.append(found[0])
        if owners[0] == owners[1]:
            return "bodies failed", (f"both surfaces of {pair.slave!r} / {pair.master!r} "
                                     f"lie on one connected body (self contact)")
        key = frozenset(zip(owners, (pair.slave, pair.master)))
        if key in seen:
            continue                 # the same pair in several steps
        seen.add(key)
        interfaces.append(Interface(names[owners[1]], pair.master, names[owners[0]],
                                    pair.slave, coupling="auto", slave=names[owners[0]],
                                    mu=pair.mu))
    bodies = []
    for name, m in zip(names, meshes):
        clamps = tuple(Clamp(s, tuple(range(first - 1, last)))
                       for s, first, last in asm.file_mesh.boundaries if s in m.node_sets)
        bodies.append(Body(name, m, STEEL, clamps))
    try:
        model = Model(tuple(bodies), interfaces=tuple(interfaces), mu=0.3)
    except QSMAError as exc:
        return "model failed", _first_line(exc)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pairing = multi_pairing(model)
    except QSMAError as exc:
        return "pairing failed", _first_line(exc)
    try:
        assembled = [assemble_body(b) for b in model.bodies]
        modes = linear_modes(model, assembled, pairing, n_modes=1)
    except QSMAError as exc:
        return "modes failed", _first_line(exc)
    return "needs preload and probe", (f"{len(bodies)} bodies, {len(interfaces)} "
                                       f"interface(s) ({pairing.coupling}), f1 = "
                                       f"{modes.f_hz[0]:.4g} Hz")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--all-types", action="store_true")
    args = ap.parse_args(argv)
    decks = sorted(p for p in args.folder.glob("*.inp")
                   if re.search(rb"^\*contact pair", p.read_bytes(), re.I | re.M))
    counts = Counter()
    for deck in decks:
        stage, detail = survey(deck, args.all_types)
        counts[stage] += 1
        print(f"{deck.name:32s} {stage:24s} {detail}")
    print()
    print(f"{'outcome':26s} decks")
    for stage, n in counts.most_common():
        print(f"{stage:26s} {n}")
    print(f"{'total':26s} {len(decks)}")
    return 0


if __name__ == "__main__":
    np.seterr(all="ignore")
    sys.exit(main())
