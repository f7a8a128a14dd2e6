"""Time the VTU files of a run: fields.vtu alone and with the time series fields.pvd.

Usage: python benchmarks/bench_vtu.py [--example sandwich-3d] [--repeat 5]

Runs the example once (5 levels), then writes, best of ``--repeat``:
``qsma.output.files.write_vtu`` (fields.vtu, three levels) and ``qsma.output.files.write_fields``
(fields.vtu and the three level files of fields.pvd, each level's fields computed
once); and the import of meshio in a fresh process. Most of the writing time is the
von Mises stress at the nodes, not the file.
"""
import argparse
import pathlib
import subprocess
import sys
import tempfile
import time

import qsma
from qsma.examples import EXAMPLES
from qsma.analysis.levels import Levels
from qsma.output.files import write_fields, write_vtu


def best(f, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--example", default="sandwich-3d")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    model = EXAMPLES[args.example](refine=1)
    res = qsma.run(model, levels=Levels.log("tip", 1e-6, 1e-4, 5))
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="bench-vtu-"))
    rows = [("write_vtu (fields.vtu)", best(lambda: write_vtu(res, tmp / "f.vtu"),
                                            args.repeat)),
            ("write_fields (fields.vtu + fields.pvd)",
             best(lambda: write_fields(res, tmp), args.repeat))]
    code = "import time; t = time.perf_counter(); import meshio; " \
           "print(time.perf_counter() - t)"
    imports = [float(subprocess.run([sys.executable, "-c", code], capture_output=True,
                                    text=True, check=True).stdout) for _ in range(3)]
    rows.append(("import meshio (fresh process)", min(imports)))
    print(f"{args.example}: {model.n_nodes} nodes, best of {args.repeat}")
    print("| step | s |\n|---|---|")
    for name, t in rows:
        print(f"| {name} | {t:.3f} |")
    print(f"fields.vtu: {(tmp / 'fields.vtu').stat().st_size} bytes")


if __name__ == "__main__":
    main()
