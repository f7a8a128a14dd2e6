"""Progress of a run (stages, levels, refinement rounds, loops), its bars on the
command line and qsma's log messages for command-line users."""
import io
import json
import threading

import pytest

import qsma
from qsma.cli import main
from qsma.examples import lap_2d
from qsma.analysis.levels import Levels
from qsma.progress import Progress
from qsma.output.folders import verify_run_folder

LEVELS = Levels.log("tip", 1e-5, 1e-3, 6)


class Recorder(Progress):
    def __init__(self):
        self.events = []
        self.threads = []

    def stage(self, name):
        self.events.append(("stage", name))

    def task(self, name, total):
        self.events.append(("task", name, total))

    def advance(self, name, done, total):
        self.events.append(("advance", name, done, total))
        if name == "levels":          # (the loops' process pool has threads of its own)
            self.threads.append(threading.active_count())


@pytest.fixture(scope="module")
def recorded():
    rec = Recorder()
    res = qsma.run(lap_2d(1), levels=LEVELS, progress=rec)
    return rec, res


def test_a_run_reports_its_stages_and_tasks(recorded):
    """The preparation stages come first (before any level is solved), then the
    levels of the ramp one by one, the refinement rounds, and a step per loop."""
    rec, res = recorded
    stages = [e[1] for e in rec.events if e[0] == "stage"]
    for name in ("assembly", "condensation", "modal", "contact", "hysteresis"):
        assert name in stages
    first_level = rec.events.index(("task", "levels", 6))
    before = {e[1] for e in rec.events[:first_level] if e[0] == "stage"}
    assert {"assembly", "condensation", "modal", "contact"} <= before
    levels = [e[2] for e in rec.events if e[:2] == ("advance", "levels")]
    assert levels == [1, 2, 3, 4, 5, 6]
    rounds = [e for e in rec.events if e[:2] == ("task", "refinement")]
    assert len(rounds) >= 1 and all(e[2] > 6 for e in rounds)
    n_loops = int((res.dissipation_method == "loop").sum())
    assert n_loops > 0
    assert ("task", "loops", n_loops) in rec.events
    loops = [e[2] for e in rec.events if e[:2] == ("advance", "loops")]
    assert loops == list(range(1, n_loops + 1))


def test_a_plain_callable_gets_the_levels(recorded):
    _, ref = recorded
    seen = []
    res = qsma.run(lap_2d(1), levels=LEVELS, progress=lambda k, n: seen.append((k, n)))
    assert seen == [(k, 6) for k in range(1, 7)]
    assert (res.zeta == ref.zeta).all()          # reporting changes nothing


def test_bars_draw_every_task_without_a_thread_of_their_own():
    """The bars are redrawn on the run's reports, not by a timer thread: the run may
    still fork its second process (qsma._infra.forked.fork_refusal refuses while another
    thread runs)."""
    from rich.console import Console
    from qsma.cli.progress import RunBars
    buf = io.StringIO()
    console = Console(file=buf, force_terminal=True, width=110, color_system=None)
    rec = Recorder()

    class Both(RunBars):
        def advance(self, name, done, total):
            super().advance(name, done, total)
            rec.advance(name, done, total)

    before = threading.active_count()
    with Both(console) as bars:
        assert threading.active_count() == before
        qsma.run(lap_2d(1), levels=LEVELS, progress=bars)
    text = buf.getvalue()
    for label in ("qsma: condensing to the interface", "load levels", "refinement round 1",
                  "loops", "6/6", "left", "qsma: done"):
        assert label in text, label
    assert set(rec.threads) == {before}


def test_log_level_and_log_file(tmp_path, capsys):
    out = tmp_path / "run"
    args = ["run", "--example", "lap-2d", "--levels", "tip:log:1e-5:1e-3:6", "--no-plots",
            "--no-vtu", "--out", str(out), "-q"]
    assert main(args) == 0
    assert "INFO" not in capsys.readouterr().err       # default: warnings and above
    log = (out / "qsma.log").read_text()
    assert "backbone refined to" in log and "loop at A=" in log
    assert "qsma.log" in verify_run_folder(out)["files"]
    assert main(args + ["--log-level", "info"]) == 0
    err = capsys.readouterr().err
    assert "qsma: INFO: backbone refined to" in err
    assert main(args[:-1] + ["--log-level", "loud"]) == 2
    assert "invalid choice: 'loud'" in capsys.readouterr().err
    assert json.loads((out / "results.json").read_text())["success"]
