"""The stages of a run and the seconds spent in each: what ``timings_s`` of a result
reports, each stage told to the run's progress (:class:`qsma.progress.Progress`)."""
from __future__ import annotations

from contextlib import contextmanager
import time

from ..progress import Progress

STAGES = ("model", "assembly", "modal", "condensation", "contact", "hysteresis",
          "postprocess", "total")


class StageClock:
    """Seconds per stage of :data:`STAGES`; a stage may be entered several times. Each
    entry is told to ``report`` (:class:`qsma.progress.Progress`)."""

    def __init__(self):
        self.t = dict.fromkeys(STAGES, 0.0)
        self.t0 = time.perf_counter()
        self.report = Progress()

    @contextmanager
    def stage(self, name):
        self.report.stage(name)
        start = time.perf_counter()
        try:
            yield
        finally:
            self.t[name] += time.perf_counter() - start

    def done(self):
        self.t["total"] = time.perf_counter() - self.t0
        return dict(self.t)
