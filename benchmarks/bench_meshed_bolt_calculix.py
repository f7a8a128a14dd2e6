"""A meshed bolt cut by a pretension section, qsma against CalculiX 2.20.

    python benchmarks/bench_meshed_bolt_calculix.py [--refine 1 2] [--mu 0.3 1.0]

The model is :func:`qsma.examples.meshed_bolt.meshed_bolt_joint` (a bolt threaded
into a clamped base plate clamps a top plate held only by the joint; the section
cuts the shank inside the top plate). CalculiX runs qsma's export of it
(``qsma export --calculix``: the same C3D8 mesh, node-to-surface penalty contact of
slope 1e4 E / h, the section as ``*PRE-TENSION SECTION, SURFACE=`` with its node
loaded by N0, then held) and its tied deck (the pairs qsma's preload closed tied,
the section's node held). Per mesh and friction coefficient the table gives: the
pairs qsma's preload leaves slipping and open; the normal force through each contact
zone (the top plate's nodal forces ``K u`` over the zone) and through the shank below
the section (the side-A cells' nodal forces on the plane z = 4), in both codes; the
largest difference of the top plate's nodal forces and of the displacement fields,
relative to their largest values; qsma's tied f0 and CalculiX's.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import shutil
import sys
import tempfile

import numpy as np

from qsma.analysis import RunOptions, StageClock, prepare
from qsma.analysis.result import load_factors
from qsma.contact.state import OPEN, SLIPPING
from qsma.deck import export_calculix
from qsma.deck.calculix import calculix_numbering
from qsma.deck.calculix_output import displacements, eigenfrequencies, run_calculix
from qsma.examples.meshed_bolt import MESHED_BOLT, meshed_bolt_joint
from qsma.fe import assemble_body
from qsma.fe.sections import cells_stiffness


def shank_force(base, u):
    """The normal force the shank's side-A cells (z from 4 to the cut) carry on the
    plane z = 4, from the base's displacements ``u``."""
    pts = base.mesh.points
    c = pts[base.mesh.cells].mean(axis=1)
    inside = (np.abs(c[:, 0] - 10) < 2) & (np.abs(c[:, 1] - 10) < 2)
    slab = np.flatnonzero(inside & (c[:, 2] > 4) & (c[:, 2] < MESHED_BOLT["z_cut"]))
    foot = np.flatnonzero(np.isclose(pts[:, 2], 4.0) & (np.abs(pts[:, 0] - 10) < 2 + 1e-9)
                          & (np.abs(pts[:, 1] - 10) < 2 + 1e-9))
    return -float((cells_stiffness(base, slab) @ u.ravel())[3 * foot + 2].sum())


def compare(refine, mu, folder: Path):
    """One row: qsma and CalculiX on ``meshed_bolt_joint(refine, mu)``."""
    m = meshed_bolt_joint(refine, mu=mu)
    deck = export_calculix(m, folder / "joint.inp", tied=True)
    text = run_calculix(folder / "joint.inp")
    first_node, _ = calculix_numbering(m)
    (u,) = [u for t, u in displacements(text, first_node[-1] + 1) if t == 1.0]
    u_c = [u[a - 1:b - 1] for a, b in zip(first_node[:-1], first_node[1:])]
    p = prepare(m, RunOptions())
    red, _, pre = p.preloaded(RunOptions(), StageClock())
    u_q = [np.asarray(x).reshape(-1, 3) for x in red.recover(pre.d, load_factors(red, 0.0))]
    base, plate = m.bodies
    K = assemble_body(plate).K
    f_c, f_q = ((K @ v[1].ravel()).reshape(-1, 3) for v in (u_c, u_q))
    z = plate.mesh.points[:, 2]
    zones = {f"z{int(h)}": (float(f_q[np.isclose(z, h), 2].sum()),
                            float(f_c[np.isclose(z, h), 2].sum())) for h in (4.0, 8.0)}
    return dict(refine=refine, mu=mu, pairs=len(pre.status),
                slip=int((pre.status == SLIPPING).sum()), open=int((pre.status == OPEN).sum()),
                zones=zones, shank=(shank_force(base, u_q[0]), shank_force(base, u_c[0])),
                df=float(np.abs(f_c - f_q).max() / np.abs(f_q).max()),
                du=max(float(np.abs(a - b).max() / np.abs(a).max()) for a, b in zip(u_q, u_c)),
                f0=(deck.mode["f0_hz"],
                    float(eigenfrequencies(run_calculix(folder / "joint-tied.inp"))[0])))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--mu", type=float, nargs="+", default=[0.3, 1.0])
    args = ap.parse_args(argv)
    if shutil.which("ccx") is None:
        print("ccx not found (apt-get install calculix-ccx)")
        return 1
    print(f"N0 = {MESHED_BOLT['pretension']:g} N")
    print(f"{'refine':>6} {'mu':>4} {'pairs':>5} {'slip':>4} {'open':>4} | "
          f"{'z=4 qsma':>9} {'z=4 ccx':>9} | {'z=8 qsma':>9} {'z=8 ccx':>9} | "
          f"{'shank q':>9} {'shank c':>9} | {'max dF':>8} {'max du':>8} | "
          f"{'f0 qsma':>12} {'f0 ccx':>10}")
    for r in args.refine:
        for mu in args.mu:
            with tempfile.TemporaryDirectory() as tmp:
                row = compare(r, mu, Path(tmp))
            (q4, c4), (q8, c8) = row["zones"]["z4"], row["zones"]["z8"]
            print(f"{r:6d} {mu:4g} {row['pairs']:5d} {row['slip']:4d} {row['open']:4d} | "
                  f"{q4:9.3f} {c4:9.3f} | {q8:9.3f} {c8:9.3f} | {row['shank'][0]:9.3f} "
                  f"{row['shank'][1]:9.3f} | {row['df']:8.2e} {row['du']:8.2e} | "
                  f"{row['f0'][0]:12.3f} {row['f0'][1]:10.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
