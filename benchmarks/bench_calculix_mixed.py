"""CalculiX's decks of a C3D10 block on a C3D20 block (two bodies of different cell
types in one file) in qsma and in ccx 2.20.

    python benchmarks/bench_calculix_mixed.py FOLDER

FOLDER holds ``cubef2f1.inp`` and ``cubef2f2.inp`` (the ``test/`` folder of the
CalculiX source distribution). Their contact is ``TIED`` and their load a shear
displacement. Two tables:

- **the tied structure as the deck has it**: qsma reads the ``TIED`` contact pair as a
  tied interface (the slave the deck's); its tied f0 (nothing can open or slip: the
  structure is linear) against ccx's first frequency in a ``*FREQUENCY`` step added
  after the deck's static step (``PERTURBATION``), with the deck's TIED penalty
  (1e7 N/mm^3, its stick slope alike), with both raised to 1e9 and to 1e11, and with
  the contact pair replaced by ``*TIE`` (CalculiX's node-to-face constraints);
- **the frictional joint it would be**: ``PRESSURE-OVERCLOSURE=TIED`` and its friction
  replaced by hard contact with mu = 0.3, the displacement of the top by a force of 1 N
  on each of its nodes (pressing the blocks together). cubef2f1 makes the tetrahedral
  face the slave, cubef2f2 the hexahedral one. The comparison is that of
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

from qsma.deck.calculix_output import eigenfrequencies, run_calculix  # noqa: E402
from qsma.fe import assemble_body  # noqa: E402
from qsma.modal import linear_modes  # noqa: E402
from qsma.model import make_pairing  # noqa: E402

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


PAIR = "*CONTACT PAIR,INTERACTION=SI1,TYPE=SURFACE TO SURFACE\n"
FREQUENCY = "*STEP,PERTURBATION\n*FREQUENCY\n1\n*END STEP\n"


def ccx_variants(text: str) -> dict:
    """The deck with a frequency step after its static one: its TIED penalty as given,
    raised to 1e9 and 1e11, and the pair as a *TIE (module docstring)."""
    if TIED not in text or PAIR not in text:
        raise SystemExit("not the cubef2f deck this script knows (its TIED interaction "
                         "or its contact pair changed)")
    penalty = lambda k: text.replace(TIED, TIED.replace("1.e7", k)) + FREQUENCY
    tie = text.replace(PAIR, "*TIE,NAME=T1\n").replace(   # the same slave, master row
        "*SURFACE INTERACTION,NAME=SI1\n" + TIED, "")
    return {"1e7": penalty("1.e7"), "1e9": penalty("1.e9"), "1e11": penalty("1.e11"),
            "tie": tie + FREQUENCY}


def tied_table(folder: Path):
    print("| deck | slave | qsma tied f0 (Hz) | ccx TIED 1e7 | ccx TIED 1e9 | ccx TIED 1e11 "
          "| ccx *TIE | rel. diff to TIED 1e9 |")
    print("|---" * 8 + "|")
    for name in ("cubef2f1", "cubef2f2"):
        text = (folder / f"{name}.inp").read_text()
        with tempfile.TemporaryDirectory() as tmp:
            deck = Path(tmp) / f"{name}.inp"
            deck.write_text(text)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                model = parse_config(read_deck(deck).config, base=deck.parent).model
                pairing = make_pairing(model)
                modes = linear_modes(model, [assemble_body(b) for b in model.bodies],
                                     pairing, n_modes=1)
            f = {}
            for key, variant in ccx_variants(text).items():
                path = Path(tmp) / f"{name}_{key}.inp"
                path.write_text(variant)
                f[key] = eigenfrequencies(run_calculix(path))[0]
        f0 = float(modes.f_hz[0])
        slave = model.body(pairing.tied_interfaces[0].slave).mesh.element
        print(f"| {name} | {slave} | {f0:.1f} | {f['1e7']:.1f} | {f['1e9']:.1f} | "
              f"{f['1e11']:.1f} | {f['tie']:.1f} | {(f['1e9'] - f0) / f0:+.1e} |", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    args = ap.parse_args(argv)
    tied_table(args.folder)
    print()
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
