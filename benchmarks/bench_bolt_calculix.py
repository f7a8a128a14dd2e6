"""The bolt preload of qsma against CalculiX: a bolted square stack, pretension only.

    python benchmarks/bench_bolt_calculix.py [--refine 1 2 3] [--penalty 1e14 1e15 ...]
                                             [--mu 0.6]

The model is :func:`qsma.examples.bolted.stack_3d_bolted` (two plates, the bottom
one on three statically determinate corner supports, the top one held only by the
joint). The CalculiX deck written here has the same idealisation as qsma: the same
C3D8 mesh and supports, one reference node per washer joined to the washer nodes by
a ``*DISTRIBUTING COUPLING`` with qsma's washer weights (the consistent nodal forces
of a uniform traction), and the pretension as a force pair on the two reference
nodes; node-to-surface penalty contact (``PRESSURE-OVERCLOSURE=LINEAR`` of slope
``K``, ``*FRICTION`` with the stick slope ``K``), the top interface as slave.

Both sides' nodal contact forces are compared as the same quantity: qsma's pair
forces ``lam`` and, for CalculiX, the interface forces ``K_top u_top`` computed with
the top plate's stiffness matrix (the C3D8 element of both codes is the same,
tests/test_elements.py) from the displacements CalculiX prints (7 digits). CalculiX's
own contact stress CSTR is printed too (it is the penalty spring force over the
slave node's area). Per mesh and penalty the table gives the closed nodes, the
total contact force, the RMS radius and peak of the pressure (nodal force / qsma's
tributary area), the largest nodal force difference relative to the largest nodal
force, and the time. The pressure centroid lies on the bolt axis in both codes (the
supports carry no load); its distance from the axis is in :func:`compare`'s row.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import shutil
import sys
import tempfile
import time

import numpy as np

from qsma.analysis import StageClock, prepare
from qsma.contact.state import OPEN, SLIPPING
from qsma.deck.calculix import calculix_number, calculix_numbering, surface_rows
from qsma.deck.calculix_output import contact_stresses, displacements
from qsma.deck.calculix_output import run_calculix as run_ccx
from qsma.examples.bolted import stack_3d_bolted
from qsma.fe import assemble_body
from qsma.fe.bolts import washer_weights
from qsma.analysis.options import RunOptions

#: sigma_inf of CalculiX's linear pressure-overclosure law (Pa): the tension a
#: node-to-face spring carries at a clearance below c0 sqrt(area). CalculiX's default,
#: E / 70000 = 2.9 MPa for steel, let the open nodes pull with up to 1.25 MPa and
#: shift the pressure (RMS radius -6.5 % at refine 1); 1 Pa makes it negligible.
TENSION = 1.0


_num = calculix_number


def _face_surface(body, facet_set, first_element):
    """``element, S<k>`` rows of the faces that form the facet set."""
    return [f"{e}, S{k}" for e, k in surface_rows(body, facet_set, first_element)]


def contact_surfaces(model, first_elem):
    """``*SURFACE`` cards of the interface: MASTER the faces of body 1, SLAVE of body 2."""
    itf, lines = model.interface, []
    for side, body_name, set_name in (("MASTER", itf.body1, itf.set1),
                                      ("SLAVE", itf.body2, itf.set2)):
        b = model.body_index(body_name)
        lines += [f"*SURFACE, NAME={side}, TYPE=ELEMENT"]
        lines += _face_surface(model.bodies[b], set_name, first_elem[b])
    return lines


def numbering(model):
    """First CalculiX node and element number of each body (1-based, bodies in
    order); the two reference nodes follow the last body's nodes."""
    return calculix_numbering(model)


def calculix_deck(model, penalty: float, tension: float = TENSION) -> str:
    """The CalculiX deck of a bolted two-body model (qsma's idealisation, see the
    module docstring); ``penalty``: contact slope K and stick slope, Pa/m;
    ``tension``: CalculiX's sigma_inf, the tension its node-to-face springs carry at
    a clearance (Pa)."""
    (bolt,) = model.bolts
    first_node, first_elem = numbering(model)
    ref = {bolt.body_a: first_node[-1], bolt.body_b: first_node[-1] + 1}
    lines = ["*HEADING", f"qsma {model.name}: bolt pretension only", "*NODE"]
    for b, n0 in zip(model.bodies, first_node):
        lines += [f"{n0 + i}, {_num(x)}, {_num(y)}, {_num(z)}"
                  for i, (x, y, z) in enumerate(b.mesh.points)]
    weights = {}
    for body_name, set_name in ((bolt.body_a, bolt.set_a), (bolt.body_b, bolt.set_b)):
        body = model.body(body_name)
        nodes, w, _, centroid = washer_weights(body, set_name)
        weights[body_name] = (nodes, w)
        lines.append(f"{ref[body_name]}, " + ", ".join(_num(c) for c in centroid))
    for k, (b, n0, e0) in enumerate(zip(model.bodies, first_node, first_elem)):
        lines.append(f"*ELEMENT, TYPE=C3D8, ELSET={b.name.upper()}")
        lines += [f"{e0 + e}, " + ", ".join(str(n0 + v) for v in c)
                  for e, c in enumerate(b.mesh.cells)]
    e_dc = first_elem[-1]
    for k, body_name in enumerate((bolt.body_a, bolt.body_b)):
        b = model.body_index(body_name)
        nodes, w = weights[body_name]
        lines += [f"*ELEMENT, TYPE=DCOUP3D, ELSET=DC{k}", f"{e_dc + k}, {ref[body_name]}",
                  f"*DISTRIBUTING COUPLING, ELSET=DC{k}"]
        lines += [f"{first_node[b] + n}, {_num(wi)}" for n, wi in zip(nodes, w)]
    lines += contact_surfaces(model, first_elem)
    lines += ["*NSET, NSET=NALL, GENERATE", f"1, {first_node[-1] + 1}, 1"]
    for b, n0 in zip(model.bodies, first_node):
        for c in b.clamps:
            comps = range(3) if c.components is None else c.components
            for comp in comps:
                lines += ["*BOUNDARY"] + [f"{n0 + n}, {comp + 1}, {comp + 1}, 0."
                                          for n in b.mesh.nodes(c.set)]
    mat = model.bodies[0].material
    lines += ["*MATERIAL, NAME=STEEL", "*ELASTIC", f"{_num(mat.E)}, {_num(mat.nu)}"]
    for b in model.bodies:
        lines.append(f"*SOLID SECTION, ELSET={b.name.upper()}, MATERIAL=STEEL")
    lines += ["*SURFACE INTERACTION, NAME=JOINT",
              "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR",
              f"{penalty:.6g}, {tension:.6g}",
              "*FRICTION", f"{_num(model.mu)}, {penalty:.6g}",
              "*CONTACT PAIR, INTERACTION=JOINT, TYPE=NODE TO SURFACE", "SLAVE, MASTER",
              "*STEP, INC=1000", "*STATIC", "0.1, 1.", "*CLOAD",
              f"{ref[bolt.body_a]}, 2, {_num(bolt.pretension)}",
              f"{ref[bolt.body_b]}, 2, {_num(-bolt.pretension)}",
              "*NODE PRINT, NSET=NALL", "U", "*CONTACT PRINT", "CSTR", "*END STEP"]
    return "\n".join(lines) + "\n"


def run_calculix(model, penalty, folder: Path, tension=TENSION):
    """Solve the deck in ``folder``: ``(displacements per body, CSTR rows, seconds)``;
    CSTR rows are ``node, pressure, shear 1, shear 2`` of the slave nodes in contact."""
    (folder / "stack.inp").write_text(calculix_deck(model, penalty, tension))
    t0 = time.perf_counter()
    text = run_ccx(folder / "stack.inp")
    seconds = time.perf_counter() - t0
    first_node, _ = numbering(model)
    full = displacements(text, first_node[-1] + 1)[-1][1]
    per_body = [full[a - 1:b - 1] for a, b in zip(first_node[:-1], first_node[1:])]
    stresses = contact_stresses(text)
    cstr = stresses[-1][1] if stresses else np.zeros((0, 4))
    return per_body, cstr, seconds


def contact_forces_from_displacements(model, u_top):
    """Normal contact force on the top plate at each of its interface nodes,
    ``(K_top u_top)_y`` (no other load acts on those nodes)."""
    top = model.body(model.interface.body2)
    K = assemble_body(top).K
    f = (K @ u_top.ravel()).reshape(-1, 3)
    return f[:, 1]


def qsma_preload(model):
    """``(pairing, preload contact result, seconds)`` of qsma."""
    t0 = time.perf_counter()
    p = prepare(model)
    _, _, pre = p.preloaded(RunOptions(), StageClock())
    return p.pairing, pre, time.perf_counter() - t0


def pressure_measures(x, area, force):
    """Total, distance of the centroid from the bolt axis, RMS radius about the axis
    and peak of ``force / area``."""
    r = np.hypot(x[:, 0], x[:, 2])
    total = float(force.sum())
    centroid = (force @ x[:, [0, 2]]) / total
    return dict(total=total, centroid=float(np.linalg.norm(centroid)),
                rms=float(np.sqrt(force @ r ** 2 / total)),
                peak=float((force / area).max()))


_QSMA = {}          # qsma's preload per (refine, mu), solved once


def compare(refine, penalty, mu=None, folder=None, tension=TENSION):
    """One row of the table: qsma and CalculiX on ``stack_3d_bolted(refine, mu)``."""
    model = stack_3d_bolted(refine, mu)
    if (refine, mu) not in _QSMA:
        _QSMA[refine, mu] = qsma_preload(model)
    pairing, pre, t_q = _QSMA[refine, mu]
    with tempfile.TemporaryDirectory() as tmp:
        u, cstr, t_c = run_calculix(model, penalty, Path(folder or tmp), tension)
    f_c = contact_forces_from_displacements(model, u[1])[pairing.nodes2]
    f_q = pre.lam[:, -1]
    q = pressure_measures(pairing.x, pairing.area, f_q)
    c = pressure_measures(pairing.x, pairing.area, f_c)
    peak_cstr = float(cstr[:, 1].max()) if len(cstr) else float("nan")
    return dict(refine=refine, penalty=penalty, pairs=len(f_q), q=q, c=c,
                peak_cstr=peak_cstr, closed_q=int((pre.status != OPEN).sum()),
                slip_q=int((pre.status == SLIPPING).sum()),
                closed_c=int((cstr[:, 1] > 0).sum()),
                max_diff=float(np.abs(f_q - f_c).max() / f_q.max()),
                t_qsma=t_q, t_ccx=t_c)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--penalty", type=float, nargs="+", default=[1e15, 1e16, 1e17])
    ap.add_argument("--mu", type=float, default=None)
    ap.add_argument("--tension", type=float, default=TENSION,
                    help="CalculiX sigma_inf, Pa (its default is E / 70000)")
    args = ap.parse_args(argv)
    if shutil.which("ccx") is None:
        print("ccx not found (apt-get install calculix-ccx)")
        return 1
    print(f"{'refine':>6} {'pairs':>5} {'K Pa/m':>7} | {'closed':>11} | {'sum qsma':>9} "
          f"{'sum ccx':>9} | {'rms r qsma':>10} {'rms r ccx':>10} mm | {'peak qsma':>9} "
          f"{'peak ccx':>9} {'CSTR':>8} MPa | {'max dF':>8} | {'t qsma':>6} {'t ccx':>6} s")
    for r in args.refine:
        for k in args.penalty:
            row = compare(r, k, args.mu, tension=args.tension)
            q, c = row["q"], row["c"]
            closed = f"{row['closed_q']}({row['slip_q']})/{row['closed_c']}"
            print(f"{r:6d} {row['pairs']:5d} {k:7.0e} | {closed:>11} | {q['total']:9.3f} "
                  f"{c['total']:9.3f} | {1e3 * q['rms']:10.6f} {1e3 * c['rms']:10.6f}    | "
                  f"{q['peak'] / 1e6:9.4f} {c['peak'] / 1e6:9.4f} "
                  f"{row['peak_cstr'] / 1e6:8.4f}     | {row['max_diff']:8.2e} | "
                  f"{row['t_qsma']:6.2f} {row['t_ccx']:6.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
