"""The 3D lap joint meshed the way an engineer's own joint arrives: tetrahedra from
Gmsh, each plate meshed on its own (the two sides of the interface do not match; the
mortar coupling joins them), read back from .msh files. Prints its size and the
stages of a whole run.

Usage: python benchmarks/bench_tet_lap.py [--size 1.0] [--top-size 1.15]
           [--outer-size 2.5] [--dissipation masing] [--repeat 1]
           [--levels tip:log:1e-6:1e-3:51] [--method auto] [--loop-workers N]
           [--keep DIR] [--mortar-only]
           [--contact-only] [--save FILE.npz] [--profile FILE.prof]

Needs the ``gmsh`` Python package (``pip install gmsh``; not a qsma dependency).

The geometry and loads are those of :func:`qsma.examples.lap_3d` (two steel plates
100 x 5 x 20 mm overlapping by 30 mm, clamped at their far ends, 8 kN on a 10 x 10 mm
washer square on each outer face). Each plate is a fragment of boxes, so that the
overlap, the washer square and the bolt axis (the probe) are edges of the mesh; the
overlap is meshed with tetrahedra of ``--size`` mm on the bottom plate and
``--top-size`` mm on the top plate, the rest with ``--outer-size`` mm. The default
sizes give about the model issue 14 quotes (a Gmsh tetrahedral lap joint of 21,761
nodes and 730 interface pairs).

``--dissipation masing`` (default) runs the ramps only, as the issue's measurement
did; ``auto`` lets qsma compute the loops where Masing's assumptions fail (they do
on this joint, docs/validation.md), which is the trustworthy answer and costs much
more.

``--mortar-only`` times the mortar coupling alone (``qsma.model.make_pairing``, the
whole pairing of the interface: slave choice, projection, frames), ``--repeat`` times,
and prints each run and the median instead of running the analysis.

``--contact-only`` prepares the model once (pairing, assembly, condensation; the tied
modes of the first run are reused) and then times the contact stage alone, ``--repeat``
times: each run solves the preload again on a new contact problem (no elimination of an
earlier run is reused) and the ramps, as :func:`qsma.run` does. ``--save`` writes every
level's f0, q, zeta, tip and stuck/slip/open counts of the last run (to compare two
codes to the bit), ``--profile`` a cProfile of the last run.
"""
import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

import qsma
from qsma._infra.resources import cpu_with_children_s
from qsma.examples.lap import LAP_3D
from qsma.cli.run import parse_levels_spec
from qsma.model import Body, Clamp, Interface, Material, Model, Pressure, Probe


def _cuts(s):
    """x cuts of each plate and z cuts of both: overlap ends, washer edges, bolt axis."""
    L, c, a, b = s["L"], s["c"], s["a_washer"], s["b"]
    xb = L - c / 2
    washer_x = [xb - a / 2, xb, xb + a / 2]
    return ([0.0, L - c] + washer_x + [L],            # bottom plate
            [L - c] + washer_x + [L, 2 * L - c],      # top plate
            [0.0, b / 2 - a / 2, b / 2 + a / 2, b])


def mesh_plate(path, xs, y0, zs, t, size_overlap, size_outer, overlap):
    """Tetrahedra of the plate ``xs[0]..xs[-1] x y0..y0+t x zs[0]..zs[-1]`` (mm
    sizes, m coordinates), written to ``path`` (Gmsh 4.1)."""
    import gmsh
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(path.stem)
        occ = gmsh.model.occ
        boxes = [(3, occ.addBox(x0, y0, z0, x1 - x0, t, z1 - z0))
                 for x0, x1 in zip(xs[:-1], xs[1:]) for z0, z1 in zip(zs[:-1], zs[1:])]
        occ.fragment(boxes[:1], boxes[1:])
        occ.synchronize()
        volumes = [tag for _, tag in gmsh.model.getEntities(3)]
        gmsh.model.addPhysicalGroup(3, volumes, name="plate")
        lo, hi = overlap
        field = gmsh.model.mesh.field
        box = field.add("Box")
        field.setNumber(box, "VIn", size_overlap * 1e-3)
        field.setNumber(box, "VOut", size_outer * 1e-3)
        for key, value in (("XMin", lo), ("XMax", hi), ("YMin", y0 - 1.0),
                           ("YMax", y0 + t + 1.0), ("ZMin", -1.0), ("ZMax", 1.0)):
            field.setNumber(box, key, value)
        field.setAsBackgroundMesh(box)
        for key in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints",
                    "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{key}", 0)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def tet_lap_model(folder, size=1.0, top_size=1.15, outer_size=2.5, mu=None):
    """The lap joint from two Gmsh files written into ``folder``: linear tetrahedra
    (qsma's mortar coupling takes linear facets only)."""
    s = LAP_3D
    L, t, c, b, a = s["L"], s["t"], s["c"], s["b"], s["a_washer"]
    xs_bottom, xs_top, zs = _cuts(s)
    xb = L - c / 2
    eps = 1e-9 * L
    steel = Material(s["E"], s["nu"], s["rho"])
    bodies = []
    for name, xs, y0, h in (("bottom", xs_bottom, 0.0, size), ("top", xs_top, t, top_size)):
        path = mesh_plate(Path(folder) / f"{name}.msh", xs, y0, zs, t, h, outer_size,
                          (L - c, L))
        mesh = qsma.read_mesh(path)
        p = mesh.points
        y_out, x_clamp = (0.0, 0.0) if name == "bottom" else (2 * t, 2 * L - c)
        in_overlap = lambda q: (q[:, 0] >= L - c - eps) & (q[:, 0] <= L + eps)
        washer = lambda q: ((np.abs(q[:, 0] - xb) <= a / 2 + eps)
                            & (np.abs(q[:, 2] - b / 2) <= a / 2 + eps))
        mesh = mesh.with_sets(
            node_sets={"clamp": np.flatnonzero(np.abs(p[:, 0] - x_clamp) < eps),
                       "probe": np.flatnonzero(np.abs(p[:, 0] - xb) < eps)},
            facet_sets={
                "interface": mesh.boundary_facets_where(
                    lambda q: (np.abs(q[:, 1] - t) < eps) & in_overlap(q)),
                "bolt": mesh.boundary_facets_where(
                    lambda q: (np.abs(q[:, 1] - y_out) < eps) & washer(q))})
        bodies.append(Body(name, mesh, steel, clamps=(Clamp("clamp"),),
                           pressures=(Pressure("bolt", s["bolt_force"] / a ** 2),)))
    return Model(bodies=tuple(bodies),
                 interface=Interface("bottom", "interface", "top", "interface",
                                     coupling="mortar"),
                 tip=Probe(sets=(("bottom", "probe"), ("top", "probe")),
                           direction=(0.0, 1.0, 0.0)),
                 mu=s["mu"] if mu is None else mu, name="lap-3d, Gmsh tetrahedra")


STAGES = ("model", "assembly", "condensation", "modal", "contact", "hysteresis",
          "postprocess")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=float, default=1.0, help="bottom overlap [mm]")
    ap.add_argument("--top-size", type=float, default=1.15, help="top overlap [mm]")
    ap.add_argument("--outer-size", type=float, default=2.5, help="outside [mm]")
    ap.add_argument("--dissipation", default="masing", choices=("masing", "auto", "loop"))
    ap.add_argument("--levels", default=None, help="as qsma run --levels")
    ap.add_argument("--method", default=None,
                    help="contact method, as qsma run --method (default: qsma's)")
    ap.add_argument("--loop-workers", type=int, default=None,
                    help="as qsma run --loop-workers (default: qsma's)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--keep", default=None, help="write the .msh files here")
    ap.add_argument("--mortar-only", action="store_true",
                    help="time the mortar pairing alone (--repeat times)")
    ap.add_argument("--contact-only", action="store_true",
                    help="prepare once, then time the contact stage (--repeat times)")
    ap.add_argument("--save", default=None, help="with --contact-only: results to .npz")
    ap.add_argument("--profile", default=None,
                    help="with --contact-only: cProfile of the last run to this file")
    args = ap.parse_args()
    scratch = None if args.keep else tempfile.TemporaryDirectory(prefix="tet_lap_")
    folder = Path(args.keep or scratch.name)
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    model = tet_lap_model(folder, args.size, args.top_size, args.outer_size)
    meshing = time.perf_counter() - t0
    if args.mortar_only:
        return time_mortar(model, args.repeat, meshing)
    levels = parse_levels_spec(args.levels) if args.levels else None
    options = {k: v for k, v in (("levels", levels), ("dissipation", args.dissipation),
                                 ("method", args.method),
                                 ("loop_workers", args.loop_workers)) if v is not None}
    if args.contact_only:
        return time_contact(model, options, args, meshing)
    runs = []
    for _ in range(args.repeat):
        w0, c0 = time.perf_counter(), cpu_with_children_s()
        res = qsma.run(model, **options)
        runs.append((time.perf_counter() - w0, cpu_with_children_s() - c0, res))
    res = runs[-1][2]
    info = res.model_info
    print(f"{model.name}: {info['n_nodes']} nodes, {info['n_dofs']} DOFs, "
          f"{info['n_pairs']} interface pairs ({info['coupling']}), "
          f"{info['n_closed_after_preload']} closed after the preload; "
          f"meshing and reading {meshing:.1f} s; "
          f"dissipation {args.dissipation}, contact method {res.solver['method']}, "
          f"{res.solver['loop_solves']} loop solves")
    print()
    print("| run | " + " | ".join(STAGES) + " | total wall | total CPU |")
    print("|---" * (len(STAGES) + 3) + "|")
    for k, (wall, cpu, r) in enumerate(runs):
        cells = [f"{r.timings_s.get(s, 0.0):.2f}" for s in STAGES]
        print(f"| {k + 1} | " + " | ".join(cells) + f" | {wall:.2f} | {cpu:.2f} |")
    if len(runs) > 1:
        print(f"median wall {statistics.median(w for w, _, _ in runs):.2f} s")
    counts = (res.n_stuck[-1], res.n_slip[-1], res.n_open[-1])
    print()
    print(f"success {res.success}: f0 = {res.f0_hz:.10g} Hz, last level q = "
          f"{res.q[-1]:.10g}, zeta = {res.zeta[-1]:.10g}, stuck/slip/open = {counts}; "
          f"{res.message}")


def time_mortar(model, repeat, meshing):
    """Print the wall time of each of ``repeat`` mortar pairings and their median."""
    from qsma.model import make_pairing
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        pairing = make_pairing(model)
        times.append(time.perf_counter() - t0)
    N = pairing.projection
    print(f"{model.name}: {sum(b.mesh.n_nodes for b in model.bodies)} nodes, "
          f"{pairing.n_pairs} interface pairs ({pairing.coupling}, slave body "
          f"{pairing.slave}), {len(pairing.master_nodes)} master nodes, projection "
          f"nnz {N.nnz}; meshing and reading {meshing:.1f} s")
    print("mortar pairing [s]: " + ", ".join(f"{t:.3f}" for t in times)
          + f"; median {statistics.median(times):.3f}")


def time_contact(model, options, args, meshing):
    """Print the contact-stage and hysteresis-stage wall seconds and the CPU seconds of
    ``args.repeat`` runs (``options`` of :func:`qsma.run`) on one preparation (each
    with its own preload and contact problem) and their medians; the last run's levels
    to ``args.save``, its profile to ``args.profile``.
    The CPU seconds count the child processes (the forked -alpha ramp, loop workers)."""
    from dataclasses import replace
    from qsma.analysis import prepare, run_prepared
    t0 = time.perf_counter()
    prepared = prepare(model)
    res = run_prepared(prepared, **options)
    modes = {k: v for k, v in prepared.cache.items() if k[0] == "mode"}
    print(f"{model.name}: {res.model_info['n_pairs']} interface pairs; meshing "
          f"{meshing:.1f} s, preparation and a first run {time.perf_counter() - t0:.1f} s")
    times, loops, cpus = [], [], []
    for k in range(args.repeat):
        fresh = replace(prepared, cache=dict(modes))     # the preload solved again
        profiler = None
        if args.profile and k == args.repeat - 1:
            import cProfile
            profiler = cProfile.Profile()
            profiler.enable()
        c0 = cpu_with_children_s()
        res = run_prepared(fresh, **options)
        cpus.append(cpu_with_children_s() - c0)
        if profiler is not None:
            profiler.disable()
            profiler.dump_stats(args.profile)
        times.append(res.timings_s["contact"])
        loops.append(res.timings_s["hysteresis"])
    print(f"contact method {res.solver['method']}, {res.solver['loop_solves']} loop solves")
    for name, values in (("contact", times), ("hysteresis (loops)", loops)):
        print(f"{name} stage wall [s]: " + ", ".join(f"{t:.2f}" for t in values)
              + f"; median {statistics.median(values):.2f}")
    print("whole run_prepared CPU [s] (contact, hysteresis, postprocess): "
          + ", ".join(f"{t:.2f}" for t in cpus) + f"; median {statistics.median(cpus):.2f}")
    counts = (res.n_stuck[-1], res.n_slip[-1], res.n_open[-1])
    print(f"f0 = {res.f0_hz!r} Hz, last q = {res.q[-1]!r}, zeta = {res.zeta[-1]!r}, "
          f"stuck/slip/open = {counts}")
    if args.save:
        np.savez(args.save, f0=res.f0_hz, q=res.q, zeta=res.zeta, tip=res.tip,
                 f_hz=res.f_hz, n_stuck=res.n_stuck, n_slip=res.n_slip, n_open=res.n_open,
                 status=res.states.status, backbone_status=res.backbone_states.status,
                 preload_status=res.preload.status, residual=res.states.residual,
                 iterations=res.states.iterations)


if __name__ == "__main__":
    main()
