"""What an interface law costs: the contact stage per level, compliant against rigid.

Usage: python benchmarks/bench_laws.py [--cases sandwich-2d:1 sandwich-3d:1 brb:2]
                                       [--laws rigid linear exponential rough]
                                       [--repeat 3]

Each case is prepared once (assembly and condensation do not depend on the law); then
for each law ``run_prepared`` (Masing's rules, the default levels) is timed
``--repeat`` times, alternating the laws so that a busy machine slows them alike.
Printed: the medians of the wall time of the ``contact`` stage (preload, both refined
ramps) and of the whole run after the preparation, the backbone points solved, the
contact time per backbone point, its ratio to the rigid law's of the same case, and
f0 and the damping of the last level (which change with the law: they are the
physics, not the cost). The laws:

* ``rigid``: hard contact, rigid stick (qsma's default);
* ``linear``: pressure-overclosure slope and stick stiffness 1e14 Pa/m (about the
  contact of ground steel surfaces);
* ``exponential``: Abaqus' exponential law, c0 = 2 um, p0 = 10 MPa, elastic stick
  1e13 Pa/m;
* ``rough``: asperities of the Brake-Reuss beam's surfaces (qsma.examples.brb,
  BRB_ROUGH), elastic-plastic, frozen on their unloading after the preload.
"""
from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time

from qsma.analysis import prepare, run_prepared
from qsma.contact.laws import (ElasticStick, ExponentialPressure, InterfaceLaw,
                               LinearPressure, RoughSurface)
from qsma.examples import EXAMPLES


def laws():
    from qsma.examples.brb import BRB_ROUGH
    return {
        "rigid": None,
        "linear": InterfaceLaw(LinearPressure(1e14), ElasticStick(1e14)),
        "exponential": InterfaceLaw(ExponentialPressure(2e-6, 1e7), ElasticStick(1e13)),
        "rough": InterfaceLaw(RoughSurface(**BRB_ROUGH)),
    }


def with_law(model, law):
    """``model`` with ``law`` on every interface."""
    if model.interface is not None:
        return dataclasses.replace(model, interface=dataclasses.replace(model.interface,
                                                                        law=law))
    return dataclasses.replace(model, interfaces=tuple(
        dataclasses.replace(i, law=law) for i in model.interfaces))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["sandwich-2d:1", "sandwich-3d:1", "brb:2"])
    ap.add_argument("--laws", nargs="+", default=["rigid", "linear", "exponential", "rough"])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    table = laws()
    print(f"{'case':>14} {'law':>12} | {'contact s':>9} {'run s':>7} {'points':>6} "
          f"{'ms/point':>8} {'/ rigid':>7} | {'f0 Hz':>10} {'zeta last':>10} success")
    for case in args.cases:
        name, _, refine = case.partition(":")
        base = EXAMPLES[name](refine=int(refine or 1))
        prepared = prepare(base)
        times = {law: [] for law in args.laws}
        last = {}
        for _ in range(args.repeat):
            for law in args.laws:
                p = dataclasses.replace(prepared, model=with_law(base, table[law]),
                                        cache={})
                t0 = time.perf_counter()
                res = run_prepared(p, dissipation="masing")
                wall = time.perf_counter() - t0
                times[law].append((res.timings_s["contact"], wall))
                last[law] = res
        rigid = None
        for law in args.laws:
            contact = statistics.median(t[0] for t in times[law])
            wall = statistics.median(t[1] for t in times[law])
            res = last[law]
            points = res.solver["backbone_points"] + res.solver["negative_ramp_levels"]
            per = 1e3 * contact / points
            rigid = per if law == "rigid" else rigid
            ratio = f"{per / rigid:7.2f}" if rigid else "      -"
            print(f"{case:>14} {law:>12} | {contact:9.3f} {wall:7.2f} {points:6d} {per:8.2f} "
                  f"{ratio} | {res.f0_hz:10.4f} {res.zeta[-1]:10.3e} {res.success}",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
