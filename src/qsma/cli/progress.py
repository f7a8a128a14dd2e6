"""Progress bars and log messages of the command line on stderr (rich).

A run shows one line for its current stage (assembly, condensation, tied modes,
contact ramps, loops) with the time spent in it, and beneath it a bar per counted
task (the load levels, the refinement rounds of the ramp, the loops) with the time
left estimated from the steps done so far. The bars are redrawn when the analysis
reports progress, not by a timer: a timer thread would keep the analysis from
forking its second process (:func:`qsma._infra.forked.fork_refusal` refuses while another
thread runs), so a long single step (a factorisation) shows as a stage whose clock
moves on at its end.

Log messages of qsma (``logging.getLogger("qsma")``: refinements, fallbacks, the
processes used) go to stderr at ``--log-level`` and above, printed above the bars
while they are shown, and at every level to ``qsma.log`` in the result folder.
"""
from __future__ import annotations

import logging
import sys

from ..progress import Progress

#: What the stage line says during each stage of :data:`qsma.analysis.STAGES`.
STAGE_TEXT = {"model": "pairing the interface", "assembly": "assembling the bodies",
              "modal": "tied modes", "condensation": "condensing to the interface",
              "contact": "contact ramps", "hysteresis": "hysteresis loops",
              "postprocess": "results", "total": "done"}
#: Labels of the counted tasks (:data:`qsma.progress.TASKS`).
TASK_TEXT = {"levels": "load levels", "refinement": "refinement round",
             "loops": "loops"}
LOG_LEVELS = ("debug", "info", "warning", "error")
#: Format of the log lines on stderr and in qsma.log.
CONSOLE_FORMAT = "qsma: %(levelname)s: %(message)s"
FILE_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
LOG_NAME = "qsma.log"


def _bars(console, transient=False):
    """A rich progress display: description, bar, count, time spent, time left; a
    task without a total (the stage line) shows its description and time only."""
    from rich.progress import (BarColumn, Progress as Bars, ProgressColumn, TextColumn,
                               TimeElapsedColumn, TimeRemainingColumn)
    from rich.text import Text

    class Counted(ProgressColumn):
        """``column`` where the task has a total, else nothing."""

        def __init__(self, column=None, text=None):
            super().__init__()
            self.column, self.text = column, text

        def render(self, task):
            if task.total is None:
                return Text("")
            if self.text is not None:
                return Text(self.text.format(task=task), style="progress.download")
            return self.column.render(task)

    return Bars(TextColumn("{task.description}"),
                Counted(BarColumn(bar_width=30)),
                Counted(text="{task.completed:.0f}/{task.total:.0f}"),
                TimeElapsedColumn(),
                Counted(text="left"), Counted(TimeRemainingColumn()),
                console=console, auto_refresh=False, transient=transient,
                redirect_stdout=False, redirect_stderr=False)


def stderr_console():
    """The rich console of stderr."""
    from rich.console import Console
    return Console(file=sys.stderr, highlight=False)


class RunBars(Progress):
    """A run's progress as nested bars on a rich console (see the module docstring);
    a context manager that shows them."""

    def __init__(self, console=None):
        self.console = console or stderr_console()
        self.bars = _bars(self.console)
        self.top = self.bars.add_task("qsma: starting", total=None)
        self.tasks = {}
        self.rounds = 0

    def __enter__(self):
        self.bars.start()
        self.bars.refresh()
        return self

    def __exit__(self, *exc):
        if exc[0] is None:
            self.stage("total")
            self.bars.stop_task(self.top)
        self.bars.stop()
        return False

    def stage(self, name):
        self.bars.update(self.top, description=f"qsma: {STAGE_TEXT.get(name, name)}")
        self.bars.refresh()

    def task(self, name, total):
        label = TASK_TEXT.get(name, name)
        if name == "refinement":
            self.rounds += 1
            label = f"{label} {self.rounds}"
        if name in self.tasks:
            self.bars.reset(self.tasks[name], total=total, description=f"  {label}")
        else:
            self.tasks[name] = self.bars.add_task(f"  {label}", total=total)
        self.bars.refresh()

    def advance(self, name, done, total):
        if name in self.tasks:
            self.bars.update(self.tasks[name], completed=done, total=total)
            self.bars.refresh()


class CountBar:
    """One bar counting ``progress(done, total)`` calls (a study's cases)."""

    def __init__(self, label, console=None):
        self.bars = _bars(console or stderr_console())
        self.task = self.bars.add_task(label, total=None)

    def __enter__(self):
        self.bars.start()
        return self

    def __exit__(self, *exc):
        self.bars.stop()
        return False

    def __call__(self, done, total):
        self.bars.update(self.task, completed=done, total=total)
        self.bars.refresh()


class _StderrHandler(logging.Handler):
    """Log lines on whatever ``sys.stderr`` is when they are emitted (so that they
    follow a redirection made after the handler, e.g. by a test)."""

    def __init__(self, console=None):
        super().__init__()
        self.console = console

    def emit(self, record):
        try:
            text = self.format(record)
            if self.console is not None and self.console.is_terminal:
                self.console.print(text, markup=False, highlight=False, soft_wrap=True)
            else:
                print(text, file=sys.stderr)
        except Exception:                   # as logging.StreamHandler: never raise
            self.handleError(record)


class LogSetup:
    """qsma's log messages during a command: to stderr at ``level`` and above (above
    the progress bars of the handler's ``console`` while they are shown) and, once
    :meth:`to_file` names one, to a file at ``info`` and above (``debug`` too when
    ``level`` is ``debug``). Undone on :meth:`close`."""

    def __init__(self, level="warning"):
        self.level = getattr(logging, level.upper())
        self.logger = logging.getLogger("qsma")
        self.console_handler = _StderrHandler()
        self.console_handler.setLevel(self.level)
        self.console_handler.setFormatter(logging.Formatter(CONSOLE_FORMAT))
        self.file_handler = None
        self.previous = self.logger.level
        self.logger.addHandler(self.console_handler)
        self.logger.setLevel(self.level)

    def to_file(self, path):
        """Write the messages from now on to ``path`` as well."""
        level = min(self.level, logging.INFO)
        self.file_handler = logging.FileHandler(path, encoding="utf-8")
        self.file_handler.setLevel(level)
        self.file_handler.setFormatter(logging.Formatter(FILE_FORMAT))
        self.logger.addHandler(self.file_handler)
        self.logger.setLevel(level)

    def close_file(self):
        """Stop writing to the file (flushed and closed: it may be listed now)."""
        if self.file_handler is not None:
            self.logger.removeHandler(self.file_handler)
            self.file_handler.close()
            self.file_handler = None
            self.logger.setLevel(self.level)

    def close(self):
        self.close_file()
        self.logger.removeHandler(self.console_handler)
        self.logger.setLevel(self.previous)


__all__ = ["RunBars", "CountBar", "LogSetup", "LOG_LEVELS", "LOG_NAME"]
