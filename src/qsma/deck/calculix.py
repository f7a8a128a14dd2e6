"""A qsma model written as a runnable CalculiX 2.20 deck of the same QSMA, so that a
result of qsma can be checked by another code (:func:`export_calculix`; the command
``qsma export --calculix OUT.inp``; docs/mesh-io.md, "Export to CalculiX").

The deck holds the same discrete problem as qsma: every body's nodes and elements (the
element qsma computes, by its Abaqus name), one material and solid section per body,
the clamps as ``*BOUNDARY``, grounded springs as ``SPRING1`` and point masses as
``MASS`` elements (each node with its share), the bolts of a 3D model as distributing
couplings, a pretension section and a spring (:mod:`qsma.deck.calculix_bolts`), one
``*CONTACT PAIR`` per interface with its ``*SURFACE INTERACTION`` (the interface law
and ``*FRICTION``), and the steps

1. the preload: the pressures (``*DSLOAD``) and nodal forces (``*CLOAD``) of the
   ``preload`` pattern and the bolts' pretensions, nonlinear static with frictional
   contact; the bolts are locked (``*BOUNDARY, FIXED`` on their pretension nodes) in
   the steps after it;
2. the tied modes: ``*FREQUENCY, PERTURBATION`` about the preloaded state. CalculiX
   keeps the contact elements of the end of step 1 in the stiffness: a closed pair is
   held by its normal penalty and its stick slope, an open one is free, which is qsma's
   tied structure (closed pairs tied, open ones free) up to the penalty (hard law) or
   exactly its layer's springs (a linear law);
3. with ``amplitudes``: for each modal force ``A`` static steps of the modal load
   ``alpha M phi`` (qsma's mass-normalised loaded mode, as nodal forces ``*CLOAD``):
   0 -> +A, then ``cycles`` cycles +A -> -A -> +A, in ``steps`` fixed increments per
   branch, with the displacements printed at every increment. ``q = phi^T M (u -
   u_pre)`` of the printed displacements against ``alpha`` is the loop, its area the
   dissipation of each cycle (:func:`qsma.deck.calculix_output.cycle_dissipations`);
   the last cycle is the one to compare with qsma's stabilised loop, a first cycle can
   differ from it (pairs that slip once after the preload).

qsma's hard contact becomes a stiff linear penalty (CalculiX's node-to-surface contact
is a penalty method): slope :data:`PENALTY_FACTOR` ``E / h`` (``E`` the stiffer body's
modulus, ``h`` the shortest edge of the interface's facets), the same as stick slope;
contact forces then differ from qsma's by about ``1 / PENALTY_FACTOR`` of their size
(the slope is written in a comment beside it). A linear, exponential (CalculiX's form)
or tabular law is written as CalculiX's own; an elastic stick as the stick slope.
What CalculiX 2.20 cannot express is refused by name (:class:`CalculixRefusal`, an
:class:`~qsma.errors.InputError`), never changed silently.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .._infra.files import atomic_write
from ..errors import InputError
from .calculix_cards import (FIELD_CONTROLS, LOOP_CYCLES, LOOP_STEPS, PENALTY_FACTOR,
                             TENSION, TENSION_RANGE, CalculixRefusal,
                             _refuse_what_calculix_cannot_hold, calculix_element,
                             calculix_number, calculix_numbering, surface_rows)
from .calculix_writer import (_default_penalty, _modal_forces, _qsma_mode, _refuse_tied,
                              _Writer)


@dataclass(frozen=True, eq=False)
class CalculixDeck:
    """A model as a CalculiX deck (:func:`calculix_deck`).

    Attributes
    ----------
    text : the deck
    first_node, first_element : per body, its first CalculiX node / element number
        (1-based, bodies in the model's order; node ``i`` of body ``k`` is
        ``first_node[k] + i``); one entry more, past the last body
    penalty : per interface (model order), the normal slope written (Pa/m; the
        penalty of hard contact or the linear law's slope, None for other laws) and the
        stick slope written (the penalty where qsma's stick is rigid)
    amplitudes : the modal forces of the cyclic steps (empty: none)
    steps : per amplitude, the number of increments per branch
    cycles : per amplitude, the cycles +A -> -A -> +A after the ramp 0 -> +A
    mode : qsma's preload and loaded mode when the tied deck or cyclic steps are
        written: ``f0_hz``, ``closed`` (mask of the contact points), ``phi`` and
        ``mphi`` per body ((n_nodes, dim) arrays), else None
    path : the deck written (None: not written)
    tied_text, tied_path : the tied deck (:func:`tied_deck`), where written
    bolts : per bolt its :class:`qsma.deck.calculix_bolts.BoltLayout` (deck nodes and
        elements, axis; :func:`qsma.deck.calculix_bolts.spring_forces` reads the bolt
        forces from CalculiX's displacements)
    """

    text: str
    first_node: tuple
    first_element: tuple
    penalty: tuple
    amplitudes: tuple = ()
    steps: int = LOOP_STEPS
    cycles: int = LOOP_CYCLES
    mode: dict | None = field(default=None, repr=False)
    path: Path | None = None
    tied_text: str | None = field(default=None, repr=False)
    tied_path: Path | None = None
    bolts: tuple = ()

    def per_body(self, u: np.ndarray) -> list:
        """Split nodal rows of the whole deck (``u[i]`` of node ``i + 1``) per body."""
        return [u[a - 1:b - 1] for a, b in zip(self.first_node[:-1], self.first_node[1:])]


def export_calculix(model, path, *, options=None, amplitudes=None, penalty=None,
                    steps: int = LOOP_STEPS, cycles: int = LOOP_CYCLES,
                    tied: bool = False) -> CalculixDeck:
    """Write ``model`` as a runnable CalculiX deck to ``path`` (atomically), and with
    ``tied`` its tied deck beside it (``<stem>-tied.inp``).

    Parameters
    ----------
    model : :class:`qsma.model.Model`
    path : the ``.inp`` file written
    options : :class:`qsma.options.RunOptions` (its ``mode`` and ``n_modes``, and the
        contact solver of qsma's preload when cyclic steps need qsma's mode)
    amplitudes : modal forces ``alpha`` of the cyclic steps (a sequence), or a
        :class:`qsma.levels.Levels` (``"tip"`` levels through qsma's tied mode, as a
        run converts them); None: preload and frequency steps only
    penalty : normal (and stick) slope standing for qsma's hard contact and rigid
        stick, Pa/m (None: :data:`PENALTY_FACTOR` ``E / h`` per interface)
    steps : increments per branch of the cyclic steps
    cycles : cycles +A -> -A -> +A per amplitude, at least :data:`LOOP_CYCLES` (the
        last is compared with qsma's stabilised loop; give as many as qsma's loop
        took to settle, results.json ``loop_cycles``)
    tied : also write the tied deck (:func:`tied_deck`; runs qsma's preload)

    Returns
    -------
    CalculixDeck
    """
    deck = calculix_deck(model, options=options, amplitudes=amplitudes, penalty=penalty,
                         steps=steps, cycles=cycles, tied=tied)
    path = Path(path)
    tied_path = path.with_name(f"{path.stem}-tied{path.suffix}") if tied else None
    for where, text in ((path, deck.text), (tied_path, deck.tied_text)):
        if where is None:
            continue
        try:
            atomic_write(where, text)
        except OSError as exc:
            raise InputError(f"cannot write {where}: {exc.strerror}; choose another "
                             f"file") from None
    return replace(deck, path=path, tied_path=tied_path)


def calculix_deck(model, *, options=None, amplitudes=None, penalty=None,
                  steps: int = LOOP_STEPS, cycles: int = LOOP_CYCLES,
                  tied: bool = False) -> CalculixDeck:
    """The deck (and tied deck) of :func:`export_calculix`, not written."""
    from ..analysis.options import RunOptions
    opts = options or RunOptions()
    _refuse_what_calculix_cannot_hold(model)
    if not (isinstance(steps, (int, np.integer)) and not isinstance(steps, bool)
            and steps >= 1):
        raise InputError(f"steps must be a positive integer (increments per branch), "
                         f"got {steps!r}")
    if not (isinstance(cycles, (int, np.integer)) and not isinstance(cycles, bool)
            and cycles >= LOOP_CYCLES):
        raise InputError(f"cycles must be an integer of at least {LOOP_CYCLES} (cycles per "
                         f"amplitude: the last is compared with qsma's stabilised loop, "
                         f"the one before shows whether CalculiX's has settled), got "
                         f"{cycles!r}")
    if tied:
        _refuse_tied(model)
    writer = _Writer(model, penalty)
    mode, alphas = None, ()
    if amplitudes is not None or tied:
        mode = _qsma_mode(model, opts)
    if amplitudes is not None:
        alphas = _modal_forces(amplitudes, mode)
    text = writer.deck(opts, mode, alphas, int(steps), int(cycles))
    tied_text = _Writer(model, penalty).tied_deck(opts, mode) if tied else None
    return CalculixDeck(text, tuple(writer.first_node), tuple(writer.first_element),
                        tuple(writer.slopes), tuple(alphas), int(steps), int(cycles),
                        mode, tied_text=tied_text, bolts=tuple(writer.bolts))


__all__ = ["CalculixDeck", "CalculixRefusal", "export_calculix", "calculix_deck",
           "calculix_number", "calculix_numbering", "surface_rows", "calculix_element",
           "PENALTY_FACTOR", "TENSION", "TENSION_RANGE", "FIELD_CONTROLS", "LOOP_STEPS",
           "LOOP_CYCLES"]
