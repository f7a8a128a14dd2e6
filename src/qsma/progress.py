"""What a run reports of its progress, and to whom: no printing here.

A run (:func:`qsma.run`) tells a :class:`Progress` when each of its stages begins
(:data:`qsma.analysis.STAGES`: assembly, condensation, tied modes, contact ramps,
hysteresis loops, ...) and how far the counted tasks within them are: the load
levels of the +alpha ramp, each refinement round of it, the loops of the levels
that need one. The command line draws these as nested progress bars with estimates
of the time left (:mod:`qsma.cli.progress`); a program may subclass
:class:`Progress`, or pass a plain ``progress(k, n)`` callable, which gets the load
levels only (:func:`reporter`).
"""
from __future__ import annotations

#: The counted tasks of a run, in the order they begin: the +alpha ramp on the
#: user's levels, each refinement round of it (levels re-solved on the finer grid),
#: and the loops.
TASKS = ("levels", "refinement", "loops")


class Progress:
    """Receives the progress of a run; every method does nothing here: override the
    ones you need. Calls come from the process that runs the analysis, in order."""

    def stage(self, name: str):
        """A stage of the run begins (a name of :data:`qsma.analysis.STAGES`)."""

    def task(self, name: str, total: int):
        """A counted task of :data:`TASKS` begins with ``total`` steps (a refinement
        round begins anew with its own total)."""

    def advance(self, name: str, done: int, total: int):
        """``done`` of the ``total`` steps of task ``name`` are finished."""


class _LevelsOnly(Progress):
    """A ``progress(k, n)`` callable as a :class:`Progress`: the user's load levels."""

    def __init__(self, call):
        self.call = call

    def advance(self, name, done, total):
        if name == "levels":
            self.call(done, total)


def reporter(progress) -> Progress:
    """``progress`` as a :class:`Progress`: itself, a callable ``progress(k, n)``
    called after each load level of the user's grid, or ``None`` (nothing reported)."""
    if progress is None:
        return Progress()
    if isinstance(progress, Progress):
        return progress
    if callable(progress):
        return _LevelsOnly(progress)
    raise TypeError(f"progress must be a qsma.progress.Progress or a callable "
                    f"progress(k, n), got {type(progress).__name__}")


__all__ = ["Progress", "TASKS", "reporter"]
