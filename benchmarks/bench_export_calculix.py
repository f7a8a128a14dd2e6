"""qsma against CalculiX on the deck ``qsma export --calculix`` writes of the same model.

    python benchmarks/bench_export_calculix.py [--example sandwich-2d lap-3d]
                                               [--penalty-factor 1e3 1e4]
                                               [--amplitudes 1e-6 1e-5] [--steps 20]
                                               [--cycles N] [--mu 0.1]

Per example and penalty: the deck of :func:`qsma.deck.export_calculix` is solved by
``ccx`` and compared with qsma's run of the model: the tied frequency f0 (CalculiX's
``*FREQUENCY`` perturbation step about its preload against qsma's tied modes), the
preload's normal contact force at each contact point (qsma's ``lam``; CalculiX's
``K u - F`` of the slave body at its interface nodes, from its printed displacements,
the body's stiffness being the same element, tests/test_elements.py), the closed pairs,
the bolt forces at the end of the preload (CalculiX's spring ``k n . (u_B - u_M)``,
qsma's pretension ``N0``: force controlled in both; the bolted examples lap-3d-bolted
and brb), and with ``--amplitudes`` (linear tied tip deflections, converted as qsma's
levels) the loop dissipation of CalculiX's last cycle (``oint alpha dq``, trapezoidal)
against qsma's stabilised loop at the same modal force, and CalculiX's first cycle
beside it. The deck runs ``--cycles`` cycles per amplitude (default: as many as qsma's
loops took to settle at these amplitudes, at least two), so that the cycle compared is
a settled one in both codes.
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
import shutil
import sys
import tempfile
import time

import numpy as np

import qsma
from qsma.contact.laws import ElasticStick, InterfaceLaw, LinearPressure
from qsma.deck import export_calculix
from qsma.deck.calculix_bolts import NODES_PER_BOLT, spring_forces
from qsma.deck.calculix import PENALTY_FACTOR, _default_penalty
from qsma.deck.calculix_cards import LOOP_CYCLES
from qsma.deck.calculix_output import (contact_stresses, cycle_dissipations, displacements,
                                       eigenfrequencies, run_calculix)
from qsma.examples import EXAMPLES, brb
from qsma.examples.bolted import stack_3d_bolted
from qsma.fe import assemble_body
from qsma.analysis.levels import Levels
from qsma.analysis.options import RunOptions
from qsma.model.body import Probe


#: Variants of the examples that CalculiX can hold: the Brake-Reuss beam with a flat
#: interface (the measured one has a gap field) and trilinear hexahedra (CalculiX's
#: C3D8I is another incompatible-modes element than qsma's: its tied f0 of brb is
#: 175.7951 Hz against qsma's 175.8743).
#: The bolted square stack (its interface slips a little under the pretension) with a
#: probe: the mean vertical displacement of the top washer.
VARIANTS = {"brb-flat": lambda refine: brb(refine, surfaces="flat", element="hexahedron"),
            "stack-3d-bolted": lambda refine: replace(
                stack_3d_bolted(refine),
                tip=Probe(sets=(("top", "washer"),), direction=(0.0, 1.0, 0.0)))}


def contact_forces(model, deck, u_body, assembled, pairing):
    """Normal contact force on body 2 of the (one) interface at its contact points:
    ``(K u - F_preload) . n`` from CalculiX's displacements of that body."""
    k = model.body_index(model.interface.body2)
    a = assembled[k]
    dim = model.dim
    u = u_body[k][:, :dim].ravel()
    f = (a.K @ u - a.loads.get("preload", 0.0)).reshape(-1, dim)
    return np.einsum("ij,ij->i", f[pairing.nodes2], pairing.normals)


def compare(model, folder: Path, penalty=None, amplitudes=None, steps=20, opts=None,
            cycles=None):
    """One comparison (module docstring): a dict of the measures. With ``amplitudes``,
    qsma's loops are computed first; ``cycles`` None: as many cycles per amplitude in
    the deck as the most any of qsma's loops took to settle, at least two."""
    opts = opts or RunOptions()
    res = None
    if amplitudes is not None:
        res = qsma.run(model, opts, levels=amplitudes, dissipation="loop")
        amplitudes = Levels("alpha", tuple(res.alpha))
        if cycles is None:
            cycles = max(LOOP_CYCLES, int(np.max(res.loop_cycles)))
    t0 = time.perf_counter()
    law = model.interface.law
    deck = export_calculix(model, folder / "model.inp", options=opts, penalty=penalty,
                           amplitudes=amplitudes, steps=steps,
                           cycles=cycles or LOOP_CYCLES, tied=law is None or law.rigid)
    t_qsma = time.perf_counter() - t0
    mode, pairing = deck.mode, deck.mode["pairing"]
    t0 = time.perf_counter()
    text = run_calculix(deck.path)
    t_ccx = time.perf_counter() - t0
    f_tied = eigenfrequencies(run_calculix(deck.tied_path)) if deck.tied_path else None
    blocks = displacements(text, deck.first_node[-1] - 1
                          + NODES_PER_BOLT * len(deck.bolts))
    f_ccx = eigenfrequencies(text) if amplitudes is None else None
    f0 = mode["f0_hz"]
    # the elastic modes in order (CalculiX lists a free-free structure's rigid modes
    # among them, near zero, unsorted when friction makes the stiffness nonsymmetric)
    at = lambda f: float("nan") if f is None else float(np.sort(f[f >= 1e-3 * f0])
                                                        [opts.mode])
    n_pre = len(_preload_times(blocks))
    u_pre = deck.per_body(blocks[n_pre - 1][1][:deck.first_node[-1] - 1])
    assembled = [assemble_body(b) for b in model.bodies]
    lam_c = contact_forces(model, deck, u_pre, assembled, pairing)
    lam_q = mode["lam"][:, -1]
    itf = model.interface
    mu = itf.mu if itf.mu is not None else model.mu
    out = dict(model=model.name, pairs=pairing.n_pairs, penalty=deck.penalty[0][0],
               f0_qsma=f0, f0_tied=at(f_tied), f0_ccx=at(f_ccx),
               closed_qsma=int(mode["closed"].sum()),
               closed_ccx=int((lam_c > 1e-6 * np.abs(lam_q).max()).sum()),
               slip_qsma=int(mode["slipping"].sum()),
               slip_ccx=_slipping(_preload_cstr(text), mu, 1e-5),
               total_qsma=float(lam_q.sum()), total_ccx=float(lam_c.sum()),
               max_diff=float(np.abs(lam_q - lam_c).max() / np.abs(lam_q).max()),
               t_qsma=t_qsma, t_ccx=t_ccx,
               bolt_qsma=np.array([b.pretension for b in model.bolts]),
               bolt_ccx=spring_forces(deck.bolts, blocks[n_pre - 1][1]))
    if amplitudes is not None:
        out.update(_loops(deck, text, res))
    return out


def _slipping(forces, mu, tol) -> int:
    """Contact points whose tangential force reached ``mu`` times the normal one
    (``forces``: tangential components, normal last; ``tol`` the relative round-off
    of the numbers: CalculiX prints 7 digits)."""
    f = np.asarray(forces, float)
    t, n = np.linalg.norm(f[:, :-1], axis=1), f[:, -1]
    return int(((n > 0) & (t >= (1 - tol) * mu * n)).sum())


def _preload_cstr(text):
    """``(shear 1, shear 2, pressure)`` of CalculiX's contact stresses at the end of
    the preload (its last block at time <= 1)."""
    blocks = [rows for t, rows in contact_stresses(text) if t <= 1.0 + 1e-9]
    return blocks[-1][:, [2, 3, 1]] if blocks else np.zeros((0, 3))


def _preload_times(blocks):
    """The blocks of step 1 (times up to 1)."""
    return [t for t, _ in blocks if t <= 1.0 + 1e-9]


def _loops(deck, text, res):
    """Dissipation of CalculiX's last and first cycle at each amplitude against qsma's
    stabilised loop ``res`` (a run at the same modal forces, every level a loop)."""
    loops = cycle_dissipations(deck, text)
    q_top = lambda cycle: cycle[1][0]                  # q at +A, where the cycle starts
    return dict(alpha=np.asarray(deck.amplitudes), cycles=deck.cycles,
                q_ccx=np.array([q_top(c[-1]) for c in loops]), q_qsma=np.asarray(res.q),
                D_ccx=np.array([c[-1][2] for c in loops]),
                D_ccx_cycles=[[cycle[2] for cycle in c] for c in loops],
                D_qsma=np.asarray(res.dissipation),
                D_qsma_error=np.asarray(res.dissipation_error),
                D_qsma_first=np.asarray(res.dissipation_first_cycle),
                qsma_cycles=np.asarray(res.loop_cycles))


def _bolt_error(r) -> str:
    """The largest relative difference of CalculiX's bolt forces from the pretensions."""
    if not len(r["bolt_qsma"]):
        return "-"
    return f"{np.max(np.abs(r['bolt_ccx'] / r['bolt_qsma'] - 1)):.1e}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--example", nargs="+", default=["sandwich-2d", "lap-3d"])
    ap.add_argument("--penalty-factor", type=float, nargs="+", default=[PENALTY_FACTOR])
    ap.add_argument("--amplitudes", type=float, nargs="*", default=None,
                    help="linear tied tip deflections of the cyclic steps")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--cycles", type=int, default=None,
                    help="cycles per amplitude in the deck (default: as many as qsma's "
                         "loops took to settle, at least 2); the last one is compared")
    ap.add_argument("--mu", type=float, default=None,
                    help="the friction coefficient of the model (default: the example's)")
    ap.add_argument("--linear", type=float, nargs=2, metavar=("KN", "KT"),
                    help="a linear law (normal and stick slopes, Pa/m) on the interface "
                         "instead of the hard one: both codes then solve the same law")
    args = ap.parse_args(argv)
    if shutil.which("ccx") is None:
        print("ccx not found (apt-get install calculix-ccx)")
        return 1
    print(f"| model | K (Pa/m) | f0 qsma (Hz) | f0 ccx tied deck | rel. diff | f0 ccx "
          f"perturbation | rel. diff | closed (slipping) qsma / ccx | contact force qsma / ccx (N) | "
          f"largest nodal diff | bolt force ccx / N0 - 1 | t qsma / ccx (s) |")
    print("|---" * 12 + "|")
    loops = []
    for name in args.example:
        model = {**EXAMPLES, **VARIANTS}[name](refine=1)
        if args.mu is not None:
            model = replace(model, mu=args.mu)
        if args.linear:
            law = InterfaceLaw(LinearPressure(args.linear[0]), ElasticStick(args.linear[1]))
            model = replace(model, interface=replace(model.interface, law=law))
        for factor in args.penalty_factor:
            K = factor / PENALTY_FACTOR * _default_penalty(model, model.interface)
            K = K if not args.linear else None      # the linear law's own slopes
            levels = None if args.amplitudes is None else Levels("tip",
                                                                 tuple(args.amplitudes))
            with tempfile.TemporaryDirectory() as tmp:
                r = compare(model, Path(tmp), penalty=K, amplitudes=levels,
                            steps=args.steps, cycles=args.cycles)
            rel = lambda f: (f - r["f0_qsma"]) / r["f0_qsma"]
            K = r["penalty"]
            print(f"| {name} | {K:.3g} | {r['f0_qsma']:.6f} | {r['f0_tied']:.6f} | "
                  f"{rel(r['f0_tied']):+.2e} | {r['f0_ccx']:.6f} | {rel(r['f0_ccx']):+.2e} | "
                  f"{r['closed_qsma']} ({r['slip_qsma']}) / "
                  f"{r['closed_ccx']} ({r['slip_ccx']}) | {r['total_qsma']:.6g} / {r['total_ccx']:.6g} | "
                  f"{r['max_diff']:.2e} | {_bolt_error(r)} | {r['t_qsma']:.1f} / "
                  f"{r['t_ccx']:.1f} |", flush=True)
            if "D_ccx" in r:
                loops.append((name, K, r))
    if loops:
        print("\n| model | K (Pa/m) | alpha | q qsma | q ccx | cycles qsma / ccx | "
              "D qsma (J) | its estimate | D qsma first cycle | D ccx per cycle | "
              "ccx last / qsma |")
        print("|---" * 11 + "|")
        for name, K, r in loops:
            for a, q1, q2, nq, d1, e1, f1, dc in zip(
                    r["alpha"], r["q_qsma"], r["q_ccx"], r["qsma_cycles"], r["D_qsma"],
                    r["D_qsma_error"], r["D_qsma_first"], r["D_ccx_cycles"]):
                cycles = " / ".join(f"{d:.4e}" for d in dc)
                print(f"| {name} | {K:.3g} | {a:.4e} | {q1:.6e} | {q2:.6e} | "
                      f"{nq} / {r['cycles']} | {d1:.4e} | {e1:.1e} | {f1:.4e} | {cycles} | "
                      f"{f'{dc[-1] / d1:.4f}' if d1 > 0 else 'stuck'} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
