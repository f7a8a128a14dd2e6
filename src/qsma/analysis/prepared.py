"""What a parameter study shares between its cases: :class:`Prepared` (pairing,
assembly and static condensation done once), :func:`prepare`, and the start of every
run (pairing, units check, thread limit)."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .._infra.threads import blas_threads as threads_limited, threads_for
from ..contact.layer import interface_springs
from ..contact.registry import method_for
from ..errors import InputError
from ..model import Pressure
from ..model.pairing import make_pairing, multi_pairing
from ..reduction.condensation import refactorised_bodies
from ..units import check_model_units
from .clock import StageClock
from .options import RunOptions
from .solves import _contact_threads
from .stages import _assemble, _condense, _mode, _warn_closed_gaps, preload

#: What to change when a study varies or fits the model-wide friction coefficient of
#: a model whose interfaces set their own (:meth:`qsma.model.Model.check_mu_reaches`).
STUDY_MU_FIX = ("a study varies the model's mu only where no interface sets its own "
                "(Interface(mu=None) in Python, one [interface] table in a configuration); "
                "for the interfaces of a [[interfaces]] list, run one configuration per "
                "value of their mu")


@dataclass(frozen=True, eq=False)
class Prepared:
    r"""The part of a run that a parameter study shares between its cases.

    Assembly and static condensation do not depend on the friction coefficient nor on
    the scale of the preload: the condensed loads are linear in the applied pressures,
    so scaling the 'preload' pattern by :math:`s` scales its columns of
    :math:`F_c` and of the welded contact force :math:`W` by :math:`s`. The tied modes
    depend only on the pairs closed by the preload: they are cached by that mask.
    Pickled (to a Dask worker, or from one worker to another) it keeps the condensed
    model as computed, nothing is condensed again: see :meth:`__reduce__`.

    Attributes
    ----------
    model : the model of the cases (its ``mu`` and preload pressures are the case's)
    pairing, assembled : interface pairing and the assembled bodies
    reduced : :class:`qsma.condense.ReducedModel` with the 'preload' pattern
    preload_scale : factor applied to the 'preload' pattern of the model it was made from
    schur_backend : condensation backend used
    timings_s : seconds per stage of the preparation
    """

    model: object
    pairing: object
    assembled: tuple
    reduced: object
    preload_scale: float = 1.0
    schur_backend: str = "auto"
    timings_s: dict = None
    cache: dict = None

    def __reduce__(self):
        r"""The model, pairing and assembled bodies with the condensed model as
        computed here (``K``, ``W``, the condensed loads and functionals, the factor of
        the welded pair, each body's ``Kc``); each body's sparse factor of
        :math:`K_{EE}` (not picklable) becomes a
        :class:`qsma.condense.RefactorisedEE`, which factorises :math:`K_{EE}` of the
        shipped assembled body when a solve first asks for it. A process receiving it
        (again) thus does one sparse factorisation per body, never the condensation;
        the cache (preload solves, tied modes) stays behind."""
        reduced = replace(self.reduced, bodies=refactorised_bodies(self.reduced.bodies,
                                                                   self.assembled))
        return (Prepared, (self.model, self.pairing, self.assembled, reduced,
                           self.preload_scale, self.schur_backend, self.timings_s, {}))

    def with_mu(self, mu) -> "Prepared":
        """The same preparation for friction coefficient ``mu`` (nothing recomputed).
        Refused when an interface sets a friction coefficient of its own (other than
        ``mu``): the model's ``mu`` would not reach it."""
        return replace(self, model=self.model.with_mu(mu, STUDY_MU_FIX))

    def with_preload_scale(self, scale) -> "Prepared":
        """The same preparation with every pressure of the 'preload' pattern multiplied
        by ``scale`` relative to the model it was prepared from (no re-assembly)."""
        if not (np.isfinite(scale) and scale > 0):
            raise InputError(f"the preload scale must be a positive finite number, "
                             f"got {scale!r}")
        factor = scale / self.preload_scale
        j = self.reduced.patterns.index("preload")
        col = lambda A: np.column_stack([A[:, i] * factor if i == j else A[:, i]
                                         for i in range(A.shape[1])])
        Fc = self.reduced.Fc          # per body (two bodies), or stacked (several)
        reduced = replace(self.reduced, W=col(self.reduced.W),
                          Fc=col(Fc) if isinstance(Fc, np.ndarray) else
                          tuple(col(F) for F in Fc),
                          loads=tuple(col(L) for L in self.reduced.loads))
        return replace(self, model=_scaled_preload(self.model, factor), reduced=reduced,
                       preload_scale=float(scale))

    def preloaded(self, opts, clock):
        """``(reduced, problem, preload result)`` for this model's mu and preload scale,
        cached (the preload does not depend on the load levels nor on the mode)."""
        method = method_for(opts.method, self.model.dim, self.pairing.n_pairs)
        key = ("preload", float(self.model.mu), self.preload_scale, method,
               tuple(sorted(opts.solver_options.items())))
        if key not in self.cache:
            out = preload(self.model, self.assembled, self.pairing, method=method,
                          opts=opts.solver_options, clock=clock, reduced=self.reduced,
                          contact_threads=_contact_threads(opts))
            self.cache[key] = out, out[1].problem.__dict__.get("_zone_outer")
        out, zone = self.cache[key]
        # every run starts from the elimination of the preload, whatever the zones of
        # earlier runs grew to (qsma.contact.zone.zone_from_state reads the last one
        # cached on the problem): the same bits in every run, in any order, whether
        # its ramps and loops grew the zones in this process or in forked ones
        if zone is None:
            out[1].problem.__dict__.pop("_zone_outer", None)
        else:
            out[1].problem.__dict__["_zone_outer"] = zone
        return out

    def mode(self, closed, opts, clock, reduced=None, layer=None):
        """:func:`_mode` cached by the mask of closed pairs, the mode, ``n_modes`` and the
        interface springs of a compliant layer; its first item is a
        :class:`qsma.modal.ModesToCome` (``.result()``: every mode)."""
        springs = interface_springs(layer, closed)
        key = ("mode", np.asarray(closed, bool).tobytes(), opts.mode, opts.n_modes,
               None if springs is None else springs.tobytes())
        if key not in self.cache:
            self.cache[key] = _mode(self.model, self.assembled, self.pairing, closed, opts,
                                    clock, reduced, layer)
        return self.cache[key]


def _scaled_preload(model, factor):
    """``model`` with every pressure and nodal force of the 'preload' pattern and every
    bolt's pretension multiplied by ``factor``."""
    bodies = tuple(replace(b, pressures=tuple(
        Pressure(p.set, p.p * factor, p.load) if p.load == "preload" else p
        for p in b.pressures), forces=tuple(
        replace(f, force=tuple(v * factor for v in f.force)) if f.load == "preload" else f
        for f in b.forces)) for b in model.bodies)
    bolts = tuple(replace(b, pretension=b.pretension * factor)
                  for b in getattr(model, "bolts", ()))      # part of 'preload' too
    return replace(model, bodies=bodies, bolts=bolts)


def prepare(model, options: RunOptions | None = None, *, assembled=None) -> Prepared:
    """Pairing, assembly and static condensation of ``model``: the work a parameter
    study does once (:class:`Prepared`; :func:`run_prepared` does the rest).

    ``assembled``: per body, an :class:`qsma.fe.AssembledBody` to reuse (``None``
    entries are assembled), e.g. when only one body's material changes.
    """
    opts = options or RunOptions()
    clock, pairing, limit = _start(model, opts)
    with threads_limited(limit):
        assembled = _assemble(model, clock, keep=assembled)
        reduced = _condense(model, assembled, pairing, opts.schur_backend, clock)
    return Prepared(model, pairing, tuple(assembled), reduced, 1.0, opts.schur_backend,
                    clock.done(), {})


def _start(model, opts):
    """``(clock, pairing, BLAS thread limit)`` of a run: the interface pairing (timed as
    stage "model"; every interface of a model with several) and the thread limit of its
    size."""
    clock = StageClock()
    with clock.stage("model"):
        pairing = make_pairing(model) if model.interface is not None \
            else multi_pairing(model)
    _warn_closed_gaps(model, pairing)
    check_model_units(model)
    limit = threads_for(pairing.n_pairs * model.dim) if opts.blas_threads == "auto" \
        else opts.blas_threads
    return clock, pairing, limit
