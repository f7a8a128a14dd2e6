"""CalculiX's decks of a C3D10 block on a C3D20 block (two bodies of different cell
types in one file) in qsma and in ccx 2.20.

    python benchmarks/bench_calculix_mixed.py FOLDER

FOLDER holds ``cubef2f1.inp`` and ``cubef2f2.inp`` (the ``test/`` folder of the
CalculiX source distribution). Their contact is ``TIED`` and their load a shear
displacement, which qsma refuses (a tied contact is no joint); each is run as the
frictional joint it would be: ``PRESSURE-OVERCLOSURE=TIED`` and its friction replaced
by hard contact with mu = 0.3, the displacement of the top by a force of 1 N on each
of its nodes (pressing the blocks together). cubef2f1 makes the tetrahedral face the
slave, cubef2f2 the hexahedral one. The comparison is that of
``bench_export_calculix.compare``: qsma's model exported as a CalculiX deck
(``qsma export --calculix``), its tied structure's f0 against the tied deck's, the
preload's total contact force against CalculiX's.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys
import tempfile
import warnings

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_export_calculix import compare  # noqa: E402

from qsma.analysis.config import parse_config  # noqa: E402
from qsma.deck import read_deck  # noqa: E402

TIED = "*SURFACE BEHAVIOR,PRESSURE-OVERCLOSURE=TIED\n1.e7\n*FRICTION\n1.e30,1.e7\n"
SHEAR = "*BOUNDARY\nNtop,1,1,.01\nNbottom,1,3\n"


def pressed(text: str) -> str:
    """The deck as a frictional joint pressed together (module docstring)."""
    if TIED not in text or SHEAR not in text:
        raise SystemExit("not the cubef2f deck this script knows (its TIED interaction "
                         "or its shear step changed)")
    return (text.replace(TIED, "*FRICTION\n0.3\n")
            .replace(SHEAR, "*BOUNDARY\nNbottom,1,3\n*CLOAD\nNtop,3,-1.\n"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    args = ap.parse_args(argv)
    print("| deck | bodies | slave | pairs | f0 qsma (Hz) | f0 ccx tied deck | rel. diff | "
          "contact force qsma / ccx (N) |")
    print("|---" * 8 + "|")
    for name in ("cubef2f1", "cubef2f2"):
        with tempfile.TemporaryDirectory() as tmp:
            deck = Path(tmp) / f"{name}.inp"
            deck.write_text(pressed((args.folder / f"{name}.inp").read_text()))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                model = parse_config(read_deck(deck).config, base=deck.parent).model
                r = compare(model, Path(tmp))
        bodies = ", ".join(f"{b.mesh.element} ({b.mesh.n_cells})" for b in model.bodies)
        slave = model.body(model.interface.slave).mesh.element
        print(f"| {name} | {bodies} | {slave} | {r['pairs']} | {r['f0_qsma']:.3f} | "
              f"{r['f0_tied']:.1f} | {(r['f0_tied'] - r['f0_qsma']) / r['f0_qsma']:+.1e} | "
              f"{r['total_qsma']:.6g} / {r['total_ccx']:.6g} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
