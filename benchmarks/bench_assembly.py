"""CPU time and peak memory of assembling one body (stiffness and consistent mass).

Usage: python benchmarks/bench_assembly.py [--repeat 3] [--cases hex8-sandwich3d-r2 ...]

Each case runs in a fresh process (``--child``): the mesh is built, then
``qsma.fe.assemble_body`` is timed with ``time.process_time`` (the first assembly of
the mesh, caches empty: scikit-fem mesh, quadrature, sparsity pattern). The peak is
the child's maximum resident set (``ru_maxrss``), imports included. Reported: the
median over ``--repeat`` processes. To compare two versions of qsma, run the script
once with each on ``PYTHONPATH``.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time


def _box(n, cell_type=None):
    from qsma.mesh.generate import structured_mesh
    import numpy as np
    xs = np.linspace(0.0, 1.0, n + 1)
    return structured_mesh(xs, xs, xs, cell_type=cell_type)


def _delaunay_tets(n):
    """Tetrahedra of the Delaunay triangulation of a jittered (n+1)^3 grid."""
    import numpy as np
    from scipy.spatial import Delaunay
    from qsma.model import Mesh
    xs = np.linspace(0.0, 1.0, n + 1)
    p = np.stack(np.meshgrid(xs, xs, xs, indexing="ij"), -1).reshape(-1, 3)
    p = p + np.random.default_rng(0).uniform(-0.2, 0.2, p.shape) / n
    t = Delaunay(p).simplices
    q = p[t]
    vol = np.einsum("ij,ij->i", np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]),
                    q[:, 3] - q[:, 0])
    t = t[np.abs(vol) > 1e-12 / n ** 3]
    vol = vol[np.abs(vol) > 1e-12 / n ** 3]
    t[vol < 0] = t[vol < 0][:, [0, 2, 1, 3]]
    return Mesh(p, t, "tetra")


def _quads(nx, ny):
    import numpy as np
    from qsma.mesh.generate import structured_mesh
    return structured_mesh(np.linspace(0, 2.0, nx + 1), np.linspace(0, 1.0, ny + 1))


def _incompatible_box(n):
    """A box of n x (n - 1) x n hexahedra with incompatible modes (C3D8I)."""
    import dataclasses
    import numpy as np
    from qsma.mesh.generate import structured_mesh
    xs = np.linspace(0.0, 1.0, n + 1)
    return dataclasses.replace(structured_mesh(xs, xs[:n], xs), element="C3D8I")


def _sandwich3d(refine):
    from qsma.examples import EXAMPLES
    return EXAMPLES["sandwich-3d"](refine=refine).bodies[0].mesh


CASES = {
    "hex8-sandwich3d-r1": lambda: _sandwich3d(1),
    "hex8-sandwich3d-r2": lambda: _sandwich3d(2),
    "hex20-box-14": lambda: _box(14, "hexahedron20"),
    "tet4-delaunay-30": lambda: _delaunay_tets(30),
    "quad4-300x150": lambda: _quads(300, 150),
    "hex8-C3D8I-box-32": lambda: _incompatible_box(32),
}


def _child(case):
    import resource
    from qsma.fe import assemble_body
    from qsma.model import Body, Material
    mesh = CASES[case]()
    body = Body("b", mesh, Material(200e9, 0.3, 7800.0))
    c0 = time.process_time()
    a = assemble_body(body)
    cpu = time.process_time() - c0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"cell": mesh.cell_type, "dofs": a.n_dofs, "elements": len(mesh.cells),
                      "nnz": a.K.nnz, "cpu": cpu, "peak_mb": peak}))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return _child(args.child)
    print(f"assemble_body (K and M), CPU seconds and peak resident MB of the process, "
          f"median of {args.repeat} fresh processes")
    print("| case | cell | elements | DOFs | nnz(K) | CPU s | peak MB |")
    print("|---|---|---|---|---|---|---|")
    for case in args.cases:
        runs = []
        for _ in range(args.repeat):
            out = subprocess.run([sys.executable, __file__, "--child", case], check=True,
                                 capture_output=True, text=True, env=os.environ).stdout
            runs.append(json.loads(out))
        r = runs[0]
        cpu = statistics.median(x["cpu"] for x in runs)
        peak = statistics.median(x["peak_mb"] for x in runs)
        print(f"| {case} | {r['cell']} | {r['elements']} | {r['dofs']} | {r['nnz']} | "
              f"{cpu:.2f} | {peak:.0f} |", flush=True)


if __name__ == "__main__":
    main()
