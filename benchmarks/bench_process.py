"""CPU time of the whole ``qsma run --example sandwich-2d`` process, per stage.

Usage: python benchmarks/bench_process.py [--repeat 5] [--example sandwich-2d]

Two measurements, each the median of ``--repeat`` fresh processes:

* the stages, timed inside one process with ``time.process_time`` (CPU of every
  thread): interpreter start-up, the imports the run needs, model, analysis, results
  tables (CSV, JSON), VTU, figures, report.html;
* the real command line ``python -m qsma run --example NAME --out DIR``, timed by the
  kernel (user + system CPU of the child process, ``os.wait4``), with the figures and
  report.html and without them (``--no-plots``, which never imports matplotlib).

The analysis row is also split by the run's own stages (pairing, assembly,
condensation, tied modes, contact ramps, hysteresis, post-processing), in CPU seconds
(``qsma.analysis._Timer.stage`` wrapped in the child; nested stages count once).

The stage sum and the command-line total differ by the argument parsing, the result
folder protocol and the noise of a shared machine.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

STAGES = ("start-up", "import", "model", "analysis", "csv+json", "vtu", "plots",
          "report")


def _child(example, out):
    """Run the stages in this process; print their CPU seconds as JSON."""
    from pathlib import Path
    c = {"start-up": time.process_time()}        # interpreter up to this line
    mark = time.process_time()

    def lap(name):
        nonlocal mark
        now = time.process_time()
        c[name] = now - mark
        mark = now

    import matplotlib.backends.backend_agg  # noqa: F401  (what the figures import)
    import matplotlib.figure  # noqa: F401
    import qsma.cli  # noqa: F401
    from qsma import analysis
    from qsma.analysis import run
    by_stage = _cpu_per_stage(analysis)
    from qsma.examples import EXAMPLES
    from qsma.plots import write_plots
    from qsma.report import write_report
    from qsma.results import write_csv, write_json, write_vtu
    lap("import")
    model = EXAMPLES[example]()
    lap("model")
    res = run(model)
    lap("analysis")
    c["analysis_stages"] = by_stage
    out = Path(out)
    write_csv(res, out / "results.csv")
    write_json(res, out / "results.json")
    lap("csv+json")
    write_vtu(res, out / "fields.vtu")
    lap("vtu")
    figures = write_plots(res, out)
    lap("plots")
    write_report(res, out / "report.html", figures)
    lap("report")
    print(json.dumps(c))


def _cpu_per_stage(analysis):
    """Wrap ``analysis._Timer.stage`` so that the CPU seconds of every stage of a run
    add up in the returned dict (a stage inside another counts for the outer one)."""
    from contextlib import contextmanager
    original, record, depth = analysis._Timer.stage, {}, [0]

    @contextmanager
    def stage(self, name):
        c0 = time.process_time()
        depth[0] += 1
        try:
            with original(self, name):
                yield
        finally:
            depth[0] -= 1
            if depth[0] == 0:
                record[name] = record.get(name, 0.0) + time.process_time() - c0

    analysis._Timer.stage = stage
    return record


def _cpu_of(cmd):
    """User + system CPU seconds of the process ``cmd`` (its output discarded)."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    stdout = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"{cmd} exited with {proc.returncode}")
    return usage.ru_utime + usage.ru_stime, stdout


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--example", default="sandwich-2d")
    ap.add_argument("--child", metavar="OUT", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return _child(args.example, args.child)
    stages, totals, cli, bare = [], [], [], []
    with tempfile.TemporaryDirectory(prefix="bench-process-") as tmp:
        for i in range(args.repeat):
            cpu, out = _cpu_of([sys.executable, __file__, "--example", args.example,
                                "--child", tmp])
            stages.append(json.loads(out))
            totals.append(cpu)
            cpu, _ = _cpu_of([sys.executable, "-m", "qsma", "run", "--example",
                              args.example, "--out", os.path.join(tmp, f"run{i}")])
            cli.append(cpu)
            cpu, _ = _cpu_of([sys.executable, "-m", "qsma", "run", "--example",
                              args.example, "--no-plots", "--out",
                              os.path.join(tmp, f"bare{i}")])
            bare.append(cpu)
    med = {k: statistics.median(s[k] for s in stages) for k in STAGES}
    print(f"{args.example}: CPU seconds (user + system), median of {args.repeat} "
          f"fresh processes")
    print("| stage | CPU s | share |")
    print("|---|---|---|")
    total = statistics.median(totals)
    for k in STAGES:
        print(f"| {k} | {med[k]:.3f} | {med[k] / total:.0%} |")
        if k == "analysis":
            for name in stages[0]["analysis_stages"]:
                v = statistics.median(s["analysis_stages"].get(name, 0.0) for s in stages)
                print(f"| analysis: {name} | {v:.3f} | |")
    print(f"| stages, process total | {total:.3f} | 100% |")
    print(f"| `qsma run` process total | {statistics.median(cli):.3f} | |")
    print(f"| `qsma run --no-plots` process total | {statistics.median(bare):.3f} | |")
    print(f"(qsma run, every run: {', '.join(f'{x:.2f}' for x in cli)}; --no-plots: "
          f"{', '.join(f'{x:.2f}' for x in bare)}; load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores)")


if __name__ == "__main__":
    main()
