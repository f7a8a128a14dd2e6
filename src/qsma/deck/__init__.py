"""Abaqus / CalculiX decks as QSMA runs: the analysis part of an ``.inp`` file read into
the configuration a TOML file would hold (:func:`qsma.config.parse_config`), with what
the deck holds that the run does not use named line by line.

What is read (docs/mesh-io.md, "Running a deck"):

- bodies: the connected parts of the mesh (``part = k``), or a ``*SOLID SECTION``
  element set that is exactly one part (``cells = name``), or the instances of a deck
  with parts; each body's ``*MATERIAL`` (``*ELASTIC``, ``*DENSITY``);
- clamps: ``*BOUNDARY`` rows with zero value in the model data and the preload step
  (``ENCASTRE``, ``PINNED`` and ``XSYMM``/``YSYMM``/``ZSYMM`` too);
- the preload: the loads of the first ``*STATIC`` step: ``*CLOAD`` (forces on nodes),
  ``*DSLOAD`` (pressure on a surface), ``*DLOAD`` (pressure on faces ``P1``..``P6`` of an
  element set);
- interfaces: each ``*CONTACT PAIR`` (master = body 1, slave = body 2 and the mortar
  slave), the ``mu`` of its ``*SURFACE INTERACTION``'s ``*FRICTION`` (0 without one, as
  in CalculiX); the stick slope and ``*SURFACE BEHAVIOR`` are kept in
  :class:`SurfaceInteraction` records, not used yet;
- the number of modes of a ``*FREQUENCY`` step.

The probe and the levels are not in a deck: the caller gives them, else the probe is
the node of largest displacement in the loaded tied mode (along its largest component)
and the levels are that probe's deflections from 1e-6 to 1e-2 of the model's size.

Every other keyword is either harmless (output requests, thermal properties without a
thermal load, later steps: :class:`DeckNote` with ``refuses=False``) or would make the
run answer another problem than the deck's (constraints, nonlinear materials, thermal
loads, prescribed displacements, ...: ``refuses=True``). ``qsma run deck.inp`` stops on
the latter; ``qsma init deck.inp`` writes the configuration with all of them as
comments, for the user to decide.

One concern per module: :mod:`.records` (what a deck holds, the keywords read, named or
refused), :mod:`.reader` (:func:`read_deck`), :mod:`.loads` (supports and loads),
:mod:`.probe` (the probe and levels a deck does not give), :mod:`.toml`
(:func:`deck_toml`).
"""
from .records import (DEFAULT_LEVELS, LAW_NOTES, Deck, DeckInterface, DeckNote,
                      SurfaceInteraction, law_table)
from .reader import read_deck
from .toml import deck_toml
from .calculix import CalculixDeck, CalculixRefusal, calculix_deck, export_calculix

__all__ = ["read_deck", "deck_toml", "export_calculix", "calculix_deck", "CalculixDeck",
           "CalculixRefusal", "Deck", "DeckInterface", "DeckNote",
           "SurfaceInteraction", "LAW_NOTES", "DEFAULT_LEVELS", "law_table"]
