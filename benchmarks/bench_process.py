"""CPU and wall time of the whole ``qsma run --example sandwich-2d`` process, per stage.

Usage: python benchmarks/bench_process.py [--repeat 5] [--example sandwich-2d]
       [--baseline SRC]

Two measurements, each the median of ``--repeat`` fresh processes:

* the stages, timed inside one process with ``time.process_time`` (CPU of every
  thread): interpreter start-up, the imports the run needs, model, analysis, results
  tables (CSV, JSON), VTU, figures, report.html;
* the real command line ``python -m qsma run --example NAME --out DIR``, timed by the
  kernel (user + system CPU of the child process and of the processes it waited for,
  such as the figure worker, ``os.wait4``) and by the clock (wall seconds from the
  start of the process to its end), with the figures and report.html and without
  them (``--no-plots``, which never imports matplotlib); for this tree also with the
  figures drawn in the qsma process (``QSMA_PLOT_WORKER=0``, as on Windows), so that
  the worker's gain is a ratio measured in the same session.

The analysis row is also split by the run's own stages (pairing, assembly,
condensation, tied modes, contact ramps, hysteresis, post-processing), in CPU seconds
(``qsma.analysis.StageClock.stage`` wrapped in the child; nested stages count once).

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
    from qsma.output.plots import write_plots
    from qsma.output.report import write_report
    from qsma.output.files import write_csv, write_json, write_vtu
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
    """Wrap ``analysis.StageClock.stage`` so that the CPU seconds of every stage of a run
    add up in the returned dict (a stage inside another counts for the outer one)."""
    from contextlib import contextmanager
    original, record, depth = analysis.StageClock.stage, {}, [0]

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

    analysis.StageClock.stage = stage
    return record


def _cpu_of(cmd, env=None):
    """User + system CPU seconds of the process ``cmd`` (with its waited-for children)
    and its wall seconds (its output kept, its stderr discarded)."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            env=env)
    stdout = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"{cmd} exited with {proc.returncode}")
    return usage.ru_utime + usage.ru_stime, wall, stdout


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


#: The command lines timed (name, extra arguments, extra environment; ``None``: this
#: tree only).
COMMANDS = (("qsma run", [], {}),
            ("qsma run --no-plots", ["--no-plots"], {}),
            ("QSMA_PLOT_WORKER=0 qsma run", [], None))


def _measure(example, env, tmp, tag, this_tree):
    """One fresh process of each kind: the stages, their process's CPU total and
    (CPU, wall) of every command of :data:`COMMANDS`."""
    cpu, _, out = _cpu_of([sys.executable, __file__, "--example", example, "--child",
                           tmp], env)
    sample = {"stages": json.loads(out), "stages total": cpu}
    run = [sys.executable, "-m", "qsma", "run", "--example", example, "--out"]
    for k, (name, extra, more_env) in enumerate(COMMANDS):
        if more_env is None and not this_tree:
            continue
        env_k = dict(env, **(more_env or {"QSMA_PLOT_WORKER": "0"}))
        sample[name] = _cpu_of(run + [os.path.join(tmp, f"cmd{k}-{tag}")] + extra,
                               env_k)[:2]
    return sample


def _rows(samples):
    """Table rows (name, median s) of the samples of one source tree."""
    stages = [s["stages"] for s in samples]
    rows = [(f"{k} (CPU)", statistics.median(s[k] for s in stages)) for k in STAGES]
    at = [k for k, _ in rows].index("analysis (CPU)") + 1
    rows[at:at] = [(f"analysis: {name} (CPU)",
                    statistics.median(s["analysis_stages"].get(name, 0.0) for s in stages))
                   for name in stages[0]["analysis_stages"]]
    rows.append(("stages, process total (CPU)",
                 statistics.median(s["stages total"] for s in samples)))
    for name, _, _ in COMMANDS:
        if name in samples[0]:
            for i, what in enumerate(("CPU", "wall")):
                rows.append((f"`{name}` process ({what})",
                             statistics.median(s[name][i] for s in samples)))
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
                samples[name].append(_measure(args.example, trees[name], tmp, f"{name}{i}",
                                              name == "this"))
            loads.append(os.getloadavg()[0])
    _print_table(args, samples, loads)


def _print_table(args, samples, loads):
    names = list(samples)
    print(f"{args.example}: seconds, median of {args.repeat} fresh processes"
          + (", baseline and this tree alternating" if len(names) > 1 else ""))
    tables = {name: dict(_rows(samples[name])) for name in names}
    heads = ["baseline s", "this s"] if len(names) > 1 else ["s"]
    order = ["baseline", "this"] if len(names) > 1 else ["this"]
    print("| stage | " + " | ".join(heads) + " |")
    print("|---" * (len(heads) + 1) + "|")
    for row in tables["this"]:
        print(f"| {row} | " + " | ".join(
            f"{tables[n][row]:.3f}" if row in tables[n] else "-" for n in order) + " |")
    for name in order:
        for cmd, _, _ in COMMANDS:
            runs = [s[cmd] for s in samples[name] if cmd in s]
            if runs:
                print(f"({name}: {cmd}, every run, CPU/wall: "
                      f"{', '.join(f'{c:.2f}/{w:.2f}' for c, w in runs)})")
    if len(names) > 1:          # the pairs ran one after the other: the load is shared
        for cmd, _, _ in COMMANDS[:2]:
            for i, what in enumerate(("CPU", "wall")):
                pairs = [(t[cmd][i], b[cmd][i])
                         for t, b in zip(samples["this"], samples["baseline"])]
                print(f"({cmd}, {what}: this / baseline, median of the {len(pairs)} "
                      f"paired ratios {statistics.median(t / b for t, b in pairs):.2f})")
    this = samples["this"]
    for i, what in enumerate(("CPU", "wall")):
        ratios = [s["qsma run"][i] / s["QSMA_PLOT_WORKER=0 qsma run"][i] for s in this]
        print(f"(this tree, {what}: worker / in-process figures, median of the "
              f"{len(ratios)} paired ratios {statistics.median(ratios):.2f})")
    print(f"(load average {min(loads):.1f} to {max(loads):.1f} on {os.cpu_count()} cores)")


if __name__ == "__main__":
    main()
