"""CPU time of the whole ``qsma run --example sandwich-2d`` process, per stage.

Usage: python benchmarks/bench_process.py [--repeat 5] [--example sandwich-2d]
       [--baseline SRC]

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

``--baseline SRC`` measures a second source tree (the ``src`` folder of another
checkout, e.g. a worktree of the main branch) in the same session, its processes
alternating with this tree's, so that the load of a shared machine falls on both
columns alike.

The package's sources are compiled to bytecode (``compileall``) before the first
process, as ``pip install`` does: with ``PYTHONDONTWRITEBYTECODE`` set and no
``__pycache__``, every process would compile qsma's modules again (0.15-0.3 s of
CPU, none of it the program's).

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


def _cpu_of(cmd, env=None):
    """User + system CPU seconds of the process ``cmd`` (its output kept, its stderr
    discarded)."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            env=env)
    stdout = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"{cmd} exited with {proc.returncode}")
    return usage.ru_utime + usage.ru_stime, stdout


def _environment(src):
    """Environment of the child processes: ``src`` first on the path (``None``: as
    this process), the package's sources compiled to bytecode first."""
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([os.path.abspath(src)]
                                            + env.get("PYTHONPATH", "").split(os.pathsep))
    subprocess.run([sys.executable, "-c", "import compileall, os, qsma; "
                    "compileall.compile_dir(os.path.dirname(qsma.__file__), quiet=1)"],
                   env=env, check=True)
    return env


def _measure(example, env, tmp, tag):
    """One fresh process of each kind: (stages, process total, qsma run, --no-plots)."""
    cpu, out = _cpu_of([sys.executable, __file__, "--example", example, "--child", tmp],
                       env)
    stages = json.loads(out)
    run = [sys.executable, "-m", "qsma", "run", "--example", example, "--out"]
    cli, _ = _cpu_of(run + [os.path.join(tmp, f"run-{tag}")], env)
    bare, _ = _cpu_of(run + [os.path.join(tmp, f"bare-{tag}"), "--no-plots"], env)
    return stages, cpu, cli, bare


def _rows(samples):
    """Table rows (name, median CPU s) of the samples of one source tree."""
    stages = [s[0] for s in samples]
    rows = [(k, statistics.median(s[k] for s in stages)) for k in STAGES]
    at = [k for k, _ in rows].index("analysis") + 1
    rows[at:at] = [(f"analysis: {name}",
                    statistics.median(s["analysis_stages"].get(name, 0.0) for s in stages))
                   for name in stages[0]["analysis_stages"]]
    rows += [("stages, process total", statistics.median(s[1] for s in samples)),
             ("`qsma run` process total", statistics.median(s[2] for s in samples)),
             ("`qsma run --no-plots` process total",
              statistics.median(s[3] for s in samples))]
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--example", default="sandwich-2d")
    ap.add_argument("--baseline", metavar="SRC",
                    help="another source tree measured alternately (a before column)")
    ap.add_argument("--child", metavar="OUT", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return _child(args.example, args.child)
    trees = {"this": _environment(None)}
    if args.baseline:
        trees["baseline"] = _environment(args.baseline)
    samples = {name: [] for name in trees}
    loads = []
    with tempfile.TemporaryDirectory(prefix="bench-process-") as tmp:
        for i in range(args.repeat):
            order = list(trees) if i % 2 == 0 else list(trees)[::-1]
            for name in order:
                samples[name].append(_measure(args.example, trees[name], tmp, f"{name}{i}"))
            loads.append(os.getloadavg()[0])
    _print_table(args, samples, loads)


def _print_table(args, samples, loads):
    names = list(samples)
    print(f"{args.example}: CPU seconds (user + system), median of {args.repeat} fresh "
          f"processes" + (", baseline and this tree alternating" if len(names) > 1 else ""))
    tables = {name: dict(_rows(samples[name])) for name in names}
    heads = ["baseline CPU s", "this CPU s"] if len(names) > 1 else ["CPU s"]
    order = ["baseline", "this"] if len(names) > 1 else ["this"]
    print("| stage | " + " | ".join(heads) + " |")
    print("|---" * (len(heads) + 1) + "|")
    for row in tables["this"]:
        print(f"| {row} | " + " | ".join(
            f"{tables[n][row]:.3f}" if row in tables[n] else "-" for n in order) + " |")
    for name in order:
        runs = samples[name]
        print(f"({name}: qsma run, every run: {', '.join(f'{s[2]:.2f}' for s in runs)}; "
              f"--no-plots: {', '.join(f'{s[3]:.2f}' for s in runs)})")
    if len(names) > 1:          # the pairs ran one after the other: the load is shared
        for i, what in ((2, "qsma run"), (3, "qsma run --no-plots")):
            diff = [t[i] - b[i] for t, b in zip(samples["this"], samples["baseline"])]
            print(f"({what}: this - baseline, median of the {len(diff)} paired "
                  f"differences {statistics.median(diff):+.3f} s)")
    print(f"(load average {min(loads):.1f} to {max(loads):.1f} on {os.cpu_count()} cores)")


if __name__ == "__main__":
    main()
