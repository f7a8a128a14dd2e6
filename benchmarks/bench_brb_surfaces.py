"""The Brake-Reuss beam's tied frequency with each part of its measured surfaces.

    python benchmarks/bench_brb_surfaces.py [--refine 2]

Prepares the beam once (assembly, condensation) and runs the preload and the tied
modes (two low levels, Masing's rules) for: the flat rigid interface, the rough law on
flat surfaces, the rigid interface with the mesoscale gap, the rough law with the gap
(no masses), the gap flipped end for end and halved, and the default (rough law, gap,
bolt sets and sensor). Prints f0, the pairs closed after the preload and the least,
mean and largest preload pressure (docs/validation.md, "With its measured surfaces").
"""
from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from qsma.analysis import prepare, run_prepared
from qsma.examples.brb import BRB_MESOSCALE_GAP, brb
from qsma.analysis.levels import Levels
from qsma.model.gapfield import GapField


def variants(refine):
    flat, meas = brb(refine, surfaces="flat"), brb(refine)
    x, g = np.array(BRB_MESOSCALE_GAP[0])[:, None], np.array(BRB_MESOSCALE_GAP[1])
    with_itf = lambda **kw: dataclasses.replace(flat, interface=dataclasses.replace(
        meas.interface, **kw))
    return flat, {
        "flat, rigid": flat,
        "rough law, flat": with_itf(gap=None),
        "rigid, with the gap": with_itf(law=None),
        "rough law and gap, no masses": with_itf(),
        "  gap flipped": with_itf(gap=GapField(("x",), -x, g, source="flipped")),
        "  half the gap": with_itf(gap=GapField(("x",), x, 0.5 * g, source="half")),
        "default (rough, gap, masses)": meas,
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, default=2)
    args = ap.parse_args(argv)
    flat, table = variants(args.refine)
    base = prepare(flat)
    print(f"{'refine ' + str(args.refine):>30} | {'f0 Hz':>9} | {'closed':>7} | "
          f"{'p min / mean / max MPa':>24}")
    for name, model in table.items():
        p = base if model.bodies is flat.bodies else prepare(model)
        r = run_prepared(dataclasses.replace(p, model=model, cache={}), dissipation="masing",
                         levels=Levels.log("tip", 1e-6, 1e-5, 2))
        pressure = r.preload.P / r.pairing.area / 1e6
        print(f"{name:>30} | {r.f0_hz:9.3f} | {r.model_info['n_closed_after_preload']:3d}/"
              f"{r.pairing.n_pairs:3d} | {pressure.min():7.2f} {pressure.mean():7.2f} "
              f"{pressure.max():7.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
