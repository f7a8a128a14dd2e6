"""A compliant interface law in qsma against CalculiX with the same law, the same mesh.

    python benchmarks/bench_law_calculix.py [--refine 1] [--law linear|exponential]
                                            [--kn 2e13] [--kt 1e13] [--mu 0.6]
                                            [--levels 6] [--steps 40]

The model is :func:`qsma.examples.lap.lap_3d` (two C3D8 plates clamped at their far
ends, a bolt pressure patch on each outer face, matching interface meshes) with the
interface law ``--law``: ``linear`` (pressure-overclosure slope ``--kn``, Pa/m) or
``exponential`` (CalculiX's form: ``--c0`` clearance, ``--p0`` pressure at zero
clearance), and an elastic stick of slope ``--kt`` (Pa/m). qsma linearises a nonlinear
layer about its preload state for the ramps (docs/theory.md section 12), CalculiX
follows the curve: with ``exponential`` the backbones differ at second order in the
pressure change, the preloads not at all.

qsma runs the QSMA: preload, tied mode with the layer's springs, the backbone at
``--levels`` modal forces and the computed loop at the largest. The CalculiX deck
written here has the same idealisation: the same nodes and C3D8 elements, clamps, the
bolt pressure as ``*DLOAD`` on the same faces, node-to-surface penalty contact
(``*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR`` of slope ``kn`` and a tension of
1 Pa, ``*FRICTION`` with ``mu`` and the stick slope ``kt``), slave the top plate's
interface (matching nodes: every slave node sits on a master node, as qsma's pairs).
Step 1 is the preload; step 2 applies qsma's modal force pattern ``alpha M phi`` as
nodal forces (``*CLOAD`` under an ``*AMPLITUDE``): the ramp through qsma's levels, then
one cycle to ``-A`` and back to ``+A`` in ``--steps`` increments per branch (and a
second one), with tight equilibrium controls.

Compared: the preload's contact force at every interface node (qsma ``lam``; CalculiX
``K_top u_top`` from its printed displacements, the top plate's stiffness being the
same C3D8), the modal amplitude ``q = phi^T M (u - u_pre)`` at each level, and the
dissipation of the cycle (``oint alpha dq`` of CalculiX's second cycle, trapezoidal,
against qsma's loop).
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

import qsma
from qsma.deck.calculix_output import displacements
from qsma.contact.laws import ElasticStick, ExponentialPressure, InterfaceLaw, LinearPressure
from qsma.examples.lap import lap_3d
from qsma.fe import assemble_body
from qsma.analysis.levels import Levels

#: The tension CalculiX's node-to-face linear law carries at small clearances (Pa):
#: 1 Pa, against tens of MPa of contact pressure, leaves the law bilinear (qsma's).
TENSION = 1.0
#: CalculiX's equilibrium controls (``*CONTROLS, PARAMETERS=FIELD``): the force
#: residual ratio and the solution-correction ratio, far tighter than its defaults
#: (0.005, 0.01), so that its answer is as converged as qsma's.
FIELD_CONTROLS = "1e-6, 1e-5, , , 1e-6, 1e-5"
#: Load cycles CalculiX runs after the ramp (the last one is compared with qsma's
#: stabilised loop).
CYCLES = 4


def _bolt_bench():
    path = Path(__file__).resolve().parent / "bench_bolt_calculix.py"
    spec = importlib.util.spec_from_file_location("bench_bolt_calculix", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


bolt = _bolt_bench()
_num = bolt._num


def law_of(name, kn, kt, c0=2e-6, p0=1e7):
    normal = LinearPressure(kn) if name == "linear" else \
        ExponentialPressure(c0, p0, form="calculix")
    return InterfaceLaw(normal, ElasticStick(kt))


def model_of(refine, law, mu):
    m = lap_3d(refine, mu)
    return dataclasses.replace(m, interface=dataclasses.replace(m.interface, law=law))


def surface_behavior(law) -> list:
    """The ``*SURFACE BEHAVIOR`` card of qsma's normal law ``law``."""
    if law.name == "linear":
        return ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR", f"{law.k:.8g}, {TENSION:.6g}"]
    return ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=EXPONENTIAL", f"{law.c0:.8g}, {law.p0:.8g}"]


def calculix_deck(model, kn, kt, mphi, times, amplitude):
    """The deck (module docstring). ``mphi``: per body, the nodal force pattern
    ``M phi`` (n_nodes, 3); ``times``, ``amplitude``: the ``*AMPLITUDE`` of the modal
    force (values are the modal force ``alpha``, applied to ``M phi``)."""
    first_node, first_elem = bolt.numbering(model)
    lines = ["*HEADING", f"qsma {model.name}: compliant contact law, QSMA path", "*NODE"]
    for b, n0 in zip(model.bodies, first_node):
        lines += [f"{n0 + i}, {_num(x)}, {_num(y)}, {_num(z)}"
                  for i, (x, y, z) in enumerate(b.mesh.points)]
    for b, n0, e0 in zip(model.bodies, first_node, first_elem):
        lines.append(f"*ELEMENT, TYPE=C3D8, ELSET={b.name.upper()}")
        lines += [f"{e0 + e}, " + ", ".join(str(n0 + v) for v in c)
                  for e, c in enumerate(b.mesh.cells)]
    lines += bolt.contact_surfaces(model, first_elem)
    lines += ["*NSET, NSET=NALL, GENERATE", f"1, {first_node[-1] - 1}, 1"]
    for b, n0 in zip(model.bodies, first_node):
        for c in b.clamps:
            lines += ["*BOUNDARY"] + [f"{n0 + n}, 1, 3, 0." for n in b.mesh.nodes(c.set)]
    mat = model.bodies[0].material
    lines += ["*MATERIAL, NAME=STEEL", "*ELASTIC", f"{_num(mat.E)}, {_num(mat.nu)}"]
    for b in model.bodies:
        lines.append(f"*SOLID SECTION, ELSET={b.name.upper()}, MATERIAL=STEEL")
    lines += ["*SURFACE INTERACTION, NAME=JOINT",
              *surface_behavior(model.interface.law.normal),
              "*FRICTION", f"{_num(model.mu)}, {kt:.8g}",
              "*CONTACT PAIR, INTERACTION=JOINT, TYPE=NODE TO SURFACE", "SLAVE, MASTER",
              "*AMPLITUDE, NAME=MODAL, TIME=TOTAL TIME"]
    lines += [f"{_num(t)}, {_num(a)}" for t, a in zip(times, amplitude)]
    # step 1: the bolt pressure
    lines += ["*STEP, INC=1000", "*STATIC", "1., 1., 1., 1.",
              "*CONTROLS, PARAMETERS=FIELD", FIELD_CONTROLS, "*DLOAD"]
    for b, e0 in zip(model.bodies, first_elem):
        for p in b.pressures:
            for row in bolt._face_surface(b, p.set, e0):
                e, face = row.split(", ")
                lines.append(f"{e}, P{face[1:]}, {_num(p.p)}")
    lines += ["*NODE PRINT, NSET=NALL", "U", "*END STEP"]
    # step 2: the modal force alpha(t) M phi along the amplitude, one increment per row
    n_inc = len(times) - 1
    lines += [f"*STEP, INC={10 * n_inc}", "*STATIC, DIRECT", f"1., {_num(times[-1] - 1.0)}",
              "*CONTROLS, PARAMETERS=FIELD", FIELD_CONTROLS, "*CLOAD, AMPLITUDE=MODAL"]
    for b, n0, f in zip(model.bodies, first_node, mphi):
        for i, row in enumerate(f):
            for comp in range(3):
                if row[comp] != 0.0:
                    lines.append(f"{n0 + i}, {comp + 1}, {_num(row[comp])}")
    lines += ["*NODE PRINT, NSET=NALL", "U", "*END STEP"]
    return "\n".join(lines) + "\n"


def displacement_blocks(text, n_total):
    """Every printed displacement block of the .dat file: ``[(time, u (n, 3))]``."""
    return displacements(text, n_total)


def qsma_side(model, alphas_tip, steps):
    """qsma's run with loops at every level: result, phi per body (mass-normalised,
    the run's sign) and ``M phi`` per body."""
    res = qsma.run(model, dissipation="loop",
                   levels=Levels("tip", tuple(alphas_tip)))
    off = model.dof_offsets()
    shapes = res.modes.shapes[:, res.modes.n_rigid + res.mode_index]
    asm = [assemble_body(b) for b in model.bodies]
    phi = [shapes[off[k]:off[k + 1]] for k in range(len(model.bodies))]
    u_pre = res.fields(None)
    u_top = res.fields(len(res.alpha) - 1)
    q_top = sum(p @ (a.M @ (u - u0)) for p, a, u, u0 in zip(phi, asm, u_top, u_pre))
    if q_top * res.q[-1] < 0:
        phi = [-p for p in phi]
    mphi = [(a.M @ p).reshape(-1, 3) for a, p in zip(asm, phi)]
    return res, phi, mphi, asm


def compare(refine=1, law="linear", kn=2e13, kt=1e13, mu=0.6, n_levels=6, steps=40,
            folder=None, cycles=CYCLES, c0=2e-6, p0=1e7):
    """One comparison (module docstring); returns a dict of the measures."""
    model = model_of(refine, law_of(law, kn, kt, c0, p0), mu)
    tips = np.logspace(-6, -4.5, n_levels)
    t0 = time.perf_counter()
    res, phi, mphi, asm = qsma_side(model, tips, steps)
    t_qsma = time.perf_counter() - t0
    alpha = np.asarray(res.alpha)
    A = alpha[-1]
    branch = np.linspace(A, -A, steps + 1)[1:]
    back = np.linspace(-A, A, steps + 1)[1:]
    amp = np.concatenate([[0.0], alpha] + [branch, back] * cycles)
    times = 1.0 + np.arange(len(amp))
    deck = calculix_deck(model, kn, kt, mphi, times, amp)
    first_node, _ = bolt.numbering(model)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(folder or tmp)
        (folder / "law.inp").write_text(deck)
        t0 = time.perf_counter()
        out = subprocess.run(["ccx", "-i", "law"], cwd=folder, capture_output=True, text=True,
                             env={**os.environ, "OMP_NUM_THREADS": "1"})
        t_ccx = time.perf_counter() - t0
        text = (folder / "law.dat").read_text() if (folder / "law.dat").exists() else ""
    blocks = displacement_blocks(text, first_node[-1] - 1)
    if out.returncode != 0 or len(blocks) < len(amp):
        raise RuntimeError(f"ccx failed ({len(blocks)} of {len(amp)} increments):\n"
                           f"{out.stdout[-3000:]}")
    per_body = lambda u: [u[a - 1:b - 1] for a, b in zip(first_node[:-1], first_node[1:])]
    u_pre = per_body(blocks[0][1])
    # preload contact forces: K_top u_top at the top plate's interface nodes
    top = model.body_index(model.interface.body2)
    f_c = (asm[top].K @ u_pre[top].ravel()).reshape(-1, 3)[res.pairing.nodes2, 1]
    f_q = res.preload.lam[:, -1]
    q_c = np.array([sum(p @ (a.M @ (ub - u0).ravel()) for p, a, ub, u0
                        in zip(phi, asm, per_body(u), u_pre)) for _, u in blocks[1:]])
    n = len(alpha)
    backbone = q_c[:n]
    a_all = amp[1:]
    cycle = lambda k: slice(n - 1 + 2 * k * steps, n + 2 * (k + 1) * steps)
    D_c = [abs(np.trapezoid(a_all[cycle(k)], q_c[cycle(k)])) for k in range(cycles)]
    return dict(model=model, res=res, alpha=alpha, q_qsma=np.asarray(res.q), q_ccx=backbone,
                preload_max_diff=float(np.abs(f_q - f_c).max() / np.abs(f_q).max()),
                preload_total=(float(f_q.sum()), float(f_c.sum())),
                D_qsma=float(res.dissipation[-1]), D_qsma_error=float(
                    res.dissipation_error[-1]), D_ccx=float(D_c[-1]), D_ccx_cycles=D_c,
                cycles_qsma=int(res.loop_cycles[-1]), flags=tuple(res.flags[-1]),
                t_qsma=t_qsma, t_ccx=t_ccx)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, default=1)
    ap.add_argument("--law", choices=("linear", "exponential"), default="linear")
    ap.add_argument("--c0", type=float, default=2e-6)
    ap.add_argument("--p0", type=float, default=1e7)
    ap.add_argument("--kn", type=float, default=2e13)
    ap.add_argument("--kt", type=float, default=1e13)
    ap.add_argument("--mu", type=float, default=0.6)
    ap.add_argument("--levels", type=int, default=6)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--cycles", type=int, default=CYCLES)
    args = ap.parse_args(argv)
    if shutil.which("ccx") is None:
        print("ccx not found (apt-get install calculix-ccx)")
        return 1
    row = compare(args.refine, args.law, args.kn, args.kt, args.mu, args.levels, args.steps,
                  cycles=args.cycles, c0=args.c0, p0=args.p0)
    print(f"lap-3d refine {args.refine}, {args.law} law kn = {args.kn:.3g} Pa/m, "
          f"kt = {args.kt:.3g} Pa/m, mu = {args.mu}")
    print(f"preload: total contact force qsma {row['preload_total'][0]:.6f} N, CalculiX "
          f"{row['preload_total'][1]:.6f} N; largest nodal difference "
          f"{row['preload_max_diff']:.2e} of the largest force")
    print(f"{'alpha':>12} {'q qsma':>14} {'q ccx':>14} {'rel diff':>9}")
    for a, q1, q2 in zip(row["alpha"], row["q_qsma"], row["q_ccx"]):
        print(f"{a:12.5e} {q1:14.7e} {q2:14.7e} {abs(q1 - q2) / abs(q1):9.2e}")
    print("CalculiX cycles (oint alpha dq): "
          + ", ".join(f"{d:.6e}" for d in row["D_ccx_cycles"]) + " J")
    print(f"stabilised: qsma {row['D_qsma']:.6e} J (estimate {row['D_qsma_error']:.1e}, "
          f"{row['cycles_qsma']} cycles, flags {', '.join(row['flags'])}), CalculiX last "
          f"cycle {row['D_ccx']:.6e} J, ratio {row['D_ccx'] / row['D_qsma']:.5f}")
    print(f"time: qsma {row['t_qsma']:.1f} s, CalculiX {row['t_ccx']:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
