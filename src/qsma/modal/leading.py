"""The mode a run loads first, the other tied modes after it.

A run's ramps need one mode (its ``mode``); the others are reported (``f_hz_tied``).
In a block shift-invert iteration the lowest modes converge first: on sandwich-3d
refine 1 the first of six after 4 of the 9 block solves. :func:`leading_modes`
returns the modes up to the loaded one as soon as they pass the iteration's
convergence test, and the iteration goes on to the others on a forked process
(:class:`ModesToCome`) while the run solves its ramps; without a fork it goes on in
this process when the modes are asked for. Either way the same numbers: the loaded
mode is the one of the leading set, and the full set is the finished iteration with
its leading columns replaced by those, after checking that they are the same
eigenvalues (:func:`qsma.modal.eigen.same_eigenvalues`).
"""
from __future__ import annotations

import logging

import numpy as np

from .._infra.forked import ChildFailed, ForkedCall
from .._infra.threads import blas_threads
from ..errors import AnalysisError
from .eigen import same_eigenvalues
from .linear import check_hourglass, linear_modes, tied_operators
from .substructured import substructured_iteration, substructured_modes
from .tied import Modes

log = logging.getLogger("qsma")


def leading_modes(model, assembled, pairing, tied, n_modes, reduced, springs, leading,
                  fork=False) -> "ModesToCome":
    """The modes of :func:`qsma.modal.linear_modes`, its first ``leading`` elastic
    modes first (:attr:`ModesToCome.leading`), the rest when asked for
    (:meth:`ModesToCome.result`).

    ``fork``: finish the iteration on a forked process meanwhile (the caller has checked
    that it may fork). Where the condensed bodies do not give the modes (no ``reduced``,
    several interfaces) or fewer than ``leading`` elastic modes are computed, every mode
    is computed here at once (:func:`qsma.modal.linear_modes`)."""
    tied, springs, _, T, M, inverse = tied_operators(model, assembled, pairing, tied,
                                                     n_modes, reduced, springs)
    if inverse is None:
        return ModesToCome.finished(linear_modes(model, assembled, pairing, tied, n_modes,
                                                 reduced, springs), leading)
    iteration = substructured_iteration(inverse, M, n_modes, model, assembled)
    build = lambda lam, vec: check_hourglass(
        substructured_modes(lam, vec, inverse, M, T, tied, model, assembled), assembled)
    if iteration.k <= leading:               # the leading modes are all of them
        return ModesToCome.finished(build(*iteration.finish()), leading)
    return ModesToCome(build(*iteration.leading(leading)), iteration, build,
                       ForkedCall(lambda: _finished(iteration)) if fork else None)


#: BLAS threads of the rest of the iteration, on the forked process or here: the ramps
#: run beside it on one thread, and a second OpenBLAS thread of the child would spin on
#: their core; the same number in both places gives the same numbers.
FINISH_BLAS_THREADS = 1


def _finished(iteration):
    with blas_threads(FINISH_BLAS_THREADS):
        return iteration.finish()


class ModesToCome:
    """The leading modes now (:attr:`leading`, a :class:`Modes`), all of them later
    (:meth:`result`, computed once).

    Attributes
    ----------
    leading : Modes
        The rigid modes of a free-free assembly and the first elastic ones.
    """

    def __init__(self, leading: Modes, iteration=None, build=None, child=None):
        self.leading = leading
        self._iteration, self._build, self._child = iteration, build, child
        self._modes = None

    @classmethod
    def finished(cls, modes: Modes, leading) -> "ModesToCome":
        """All modes known already: the leading ones are their first columns."""
        m = min(modes.n_rigid + leading, len(modes.omega))
        out = cls(Modes(modes.omega[:m], modes.shapes[:, :m], modes.tied, modes.n_rigid))
        out._modes = modes
        return out

    def result(self) -> Modes:
        """Every mode, the leading ones those of :attr:`leading` (the same eigenvalues
        to the iteration's tolerance, else :class:`AnalysisError`)."""
        if self._modes is None:
            self._modes = with_leading(self._build(*self._pairs()), self.leading)
        return self._modes

    def cancel(self):
        """Stop the forked process, if any (:meth:`result` then finishes the iteration
        in this process)."""
        if self._child is not None:
            self._child.cancel()
            self._child = None

    def _pairs(self):
        """The finished iteration's ``(lam, vec)``: the child's, else computed here from
        the state the child started from (the same operations, the same numbers)."""
        child, self._child = self._child, None
        if child is not None:
            try:
                return child.result()
            except ChildFailed as exc:
                log.warning("tied modes finished again in this process: %s", exc)
        return _finished(self._iteration)


def with_leading(modes: Modes, leading: Modes) -> Modes:
    """``modes`` with its first columns replaced by those of ``leading``, which must be
    the same eigenvalues (:func:`qsma.modal.eigen.same_eigenvalues`): a leading set
    that is not the start of the finished one (a lower mode that the iteration had not
    yet found) is refused with :class:`AnalysisError` rather than reported beside a
    ramp loaded by another mode."""
    m = len(leading.omega)
    if not same_eigenvalues(leading.omega ** 2, modes.omega[:m] ** 2):
        raise AnalysisError(
            f"tied modes: the modes converged first ({_hz(leading)}) are not the lowest "
            f"of the finished iteration ({_hz(modes, m)}); the run's ramps were loaded "
            f"by another mode. Run again with n_modes = {m - leading.n_rigid} "
            f"(the loaded mode and those below it only)")
    omega, shapes = modes.omega.copy(), modes.shapes.copy()
    omega[:m], shapes[:, :m] = leading.omega, leading.shapes
    return Modes(omega, shapes, modes.tied, modes.n_rigid)


def _hz(modes, m=None):
    return ", ".join(f"{f:.6g}" for f in modes.f_hz[:m]) + " Hz"
