"""What a deck holds, as records (:class:`Deck`, :class:`DeckInterface`,
:class:`SurfaceInteraction`, :class:`DeckNote`), the keywords qsma reads, names as
harmless or refuses, and the small helpers of the reader."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from ..mesh.io.abaqus.lexer import _abaqus_float, _rows

#: Keywords a deck may hold that change nothing of a QSMA run: output requests, solver
#: controls, amplitude definitions, and the mesh keywords the mesh reader reads.
_SILENT = frozenset({
    "HEADING", "NODE", "ELEMENT", "NSET", "ELSET", "SURFACE", "PART", "END PART",
    "ASSEMBLY", "END ASSEMBLY", "INSTANCE", "END INSTANCE", "INCLUDE", "NODE PRINT",
    "EL PRINT", "NODE FILE", "EL FILE", "CONTACT FILE", "CONTACT PRINT", "NODE OUTPUT",
    "ELEMENT OUTPUT", "CONTACT OUTPUT", "OUTPUT", "RESTART", "CONTROLS", "PREPRINT",
    "SECTION PRINT", "ENERGY PRINT", "FACE PRINT", "TIME POINTS", "END STEP", "AMPLITUDE",
    "FILE FORMAT", "MONITOR", "PHYSICAL CONSTANTS", "DIAGNOSTICS"})

#: Keywords whose data do not matter to a QSMA run (no thermal load, no damping model
#: of the contact): named, the run goes on. Value: why.
_HARMLESS = {
    "EXPANSION": "thermal expansion: qsma applies no temperature",
    "CONDUCTIVITY": "a thermal property: qsma solves no heat transfer",
    "SPECIFIC HEAT": "a thermal property: qsma solves no heat transfer",
    "GAP CONDUCTANCE": "a thermal property of the contact: qsma solves no heat transfer",
    "GAP HEAT GENERATION": "a thermal property of the contact",
    "CONTACT DAMPING": "viscous contact damping: qsma's joint damping is the friction's",
    "ORIENTATION": "a local material system (the materials read are isotropic)",
    "DAMPING": "material damping: qsma's damping is the joint's friction",
    "SECTION CONTROLS": "hourglass and distortion controls of reduced-integration "
                        "elements, which qsma does not compute (their *ELEMENT is named)",
}

#: How a bolt is written in a deck, for the notes on couplings, springs and beams that
#: belong to none.
_BOLT_ONLY = ("qsma reads couplings, beams and springs only as a bolt: two distributing "
              "couplings on washer faces of two bodies, an axial member (B31 or T3D2, "
              "SPRINGA in series) with *PRE-TENSION SECTION, ELEMENT= between their "
              "reference nodes, and *CLOAD on DOF 1 of the section's node in the first "
              "*STATIC step (docs/mesh-io.md); complete the bolt, or write a [[bolts]] "
              "table (qsma init)")

#: Abaqus' connector elements: read only as bolts (:mod:`qsma.deck.connector_bolts`).
_NO_CONNECTORS = ("qsma reads connector elements (CONN3D2) only as bolts: an AXIAL "
                  "connector between the reference nodes of two distributing couplings on "
                  "washer faces, its *CONNECTOR ELASTICITY, COMPONENT=1 the stiffness, "
                  "*CONNECTOR LOAD on component 1 in the first *STATIC step the pretension "
                  "(docs/mesh-io.md); or " + _BOLT_ONLY)

#: Abaqus' general contact: qsma's interfaces are pairs of surfaces that touch.
_GENERAL_CONTACT = ("qsma reads general contact as *CONTACT INCLUSIONS, ALL EXTERIOR with "
                    "one *CONTACT PROPERTY ASSIGNMENT ', , name' (it finds the faces where "
                    "the bodies touch); for anything narrower give the faces that touch as "
                    "two *SURFACE, TYPE=ELEMENT (one per body) and join them by *CONTACT "
                    "PAIR, INTERACTION=name; pairs apart by a clearance stay open in a QSMA "
                    "and need no pair")

#: Keywords that change the structure, its material or its supports in a way qsma does
#: not model: running without them answers another problem. Value: what to do.
_REFUSED = {
    "EQUATION": "qsma has no linear constraints between DOFs (ties between a bolt's own "
                "nodes, which belong to no body, are read with the bolt)",
    "MPC": "qsma has no multi-point constraints",
    "RIGID BODY": "qsma has no rigid bodies",
    "COUPLING": _BOLT_ONLY,
    "DISTRIBUTING": _BOLT_ONLY,
    "DISTRIBUTING COUPLING": _BOLT_ONLY,
    "KINEMATIC": "qsma has no rigid (kinematic) couplings; a bolt's washers are "
                 "distributing couplings (*DISTRIBUTING COUPLING, or *COUPLING with "
                 "*DISTRIBUTING): " + _BOLT_ONLY,
    "KINEMATIC COUPLING": "qsma has no rigid (kinematic) couplings; " + _BOLT_ONLY,
    "CONNECTOR SECTION": _NO_CONNECTORS,
    "CONNECTOR BEHAVIOR": _NO_CONNECTORS,
    "CONNECTOR ELASTICITY": _NO_CONNECTORS,
    "CONNECTOR LOAD": _NO_CONNECTORS,
    "CONNECTOR MOTION": _NO_CONNECTORS,
    "CONTACT EXCLUSIONS": _GENERAL_CONTACT,
    "CONTACT INITIALIZATION ASSIGNMENT": _GENERAL_CONTACT,
    "CONTACT INITIALIZATION DATA": _GENERAL_CONTACT,
    "SURFACE PROPERTY ASSIGNMENT": _GENERAL_CONTACT,
    "CYCLIC SYMMETRY MODEL": "qsma models the whole structure, no cyclic symmetry",
    "TRANSFORM": "qsma's supports and loads are in global directions",
    "PLASTIC": "qsma's bodies are linear elastic: the preload would differ where the "
               "material yields",
    "HYPERELASTIC": "qsma's bodies are linear elastic",
    "DEFORMATION PLASTICITY": "qsma's bodies are linear elastic",
    "CREEP": "qsma's bodies are linear elastic",
    "USER MATERIAL": "qsma's bodies are linear elastic",
    "SPRING": "spring elements are read only as a bolt's member (a SPRINGA in series with "
              "its pretension section); a spring to the ground is a springs table",
    "DASHPOT": "dashpot elements are not read",
    "MASS": "mass elements are not read; a lumped mass is a masses table",
    "SHELL SECTION": "qsma reads continuum (solid) elements only",
    "BEAM SECTION": "qsma reads continuum (solid) elements, and a B31 beam only as a "
                    "bolt's member carrying its *PRE-TENSION SECTION",
    "MEMBRANE SECTION": "qsma reads continuum (solid) elements only",
    "PRE-TENSION SECTION": "qsma's bolts join two washer faces: " + _BOLT_ONLY,
    "CLEARANCE": "qsma takes the gaps from the geometry",
    "MODEL CHANGE": "qsma keeps every element and contact pair",
    "TEMPERATURE": "qsma applies no temperature field",
    "GAP": "gap elements are not read",
    "CHANGE FRICTION": "the friction of the first static step is the run's",
    "CHANGE SURFACE BEHAVIOR": "the contact of the first static step is the run's",
    "CHANGE CONTACT TYPE": "the contact of the first static step is the run's",
    "INITIAL CONDITIONS": "qsma starts from the unstressed state",
    "CFLUX": "qsma applies no heat flux",
    "DFLUX": "qsma applies no heat flux",
    "FILM": "qsma applies no heat transfer",
    "RADIATE": "qsma applies no heat transfer",
}

#: Property keywords that belong to the *MATERIAL above them.
_MATERIAL_KEYWORDS = {"ELASTIC", "DENSITY", "EXPANSION", "CONDUCTIVITY", "SPECIFIC HEAT",
                      "PLASTIC", "HYPERELASTIC", "DEFORMATION PLASTICITY", "CREEP",
                      "USER MATERIAL", "DAMPING"}
#: Property keywords that belong to the *SURFACE INTERACTION above them.
_INTERACTION_KEYWORDS = {"SURFACE BEHAVIOR", "FRICTION", "GAP CONDUCTANCE",
                         "GAP HEAT GENERATION", "CONTACT DAMPING"}
#: *BOUNDARY types and the displacement DOFs they hold.
_BOUNDARY_TYPES = {"ENCASTRE": (1, 3), "PINNED": (1, 3), "XSYMM": (1, 1),
                   "YSYMM": (2, 2), "ZSYMM": (3, 3)}
#: Levels of a deck run without --levels: the probe's linear deflection from these
#: fractions of the model's size (its bounding box diagonal), log spaced.
DEFAULT_LEVELS = (1e-6, 1e-2, 31)


@dataclass(frozen=True)
class DeckNote:
    """Something of the deck the run does not use: where, what, what to do instead;
    ``refuses``: running without it would answer another problem than the deck's."""

    where: str
    what: str
    fix: str
    refuses: bool

    def __str__(self) -> str:
        return f"{self.where}: {self.what}; {self.fix}"


#: How a deck's ``*SURFACE BEHAVIOR`` becomes qsma's interface law, where they differ.
LAW_NOTES = {
    "LINEAR": "the slope K is the layer's normal stiffness; the tension sigma_inf that "
              "CalculiX's node-to-surface springs carry at small clearances is not "
              "modelled (qsma's layer never pulls)",
    "EXPONENTIAL": "taken as CalculiX defines it, p = p0 exp(ln(100) h / c0) from the "
                   "clearance c0 (form = \"calculix\"); an Abaqus deck means Abaqus' "
                   "form (form = \"abaqus\" in the TOML of qsma init)",
    "TABULAR": "linear between the rows; beyond the last row qsma continues its slope "
               "where CalculiX keeps its pressure",
}


def law_table(record, where=""):
    """The TOML ``law`` table of a deck's interaction (``*SURFACE BEHAVIOR`` and the
    stick slope of ``*FRICTION``), or None for hard contact with rigid stick."""
    if record is None:
        return None
    law, numbers = {}, record.behavior
    kind = record.pressure_overclosure
    if kind == "LINEAR" and numbers:
        law.update(normal="linear", normal_stiffness=numbers[0])
    elif kind == "EXPONENTIAL" and len(numbers) >= 2:
        law.update(normal="exponential", clearance=numbers[0], pressure_at_zero=numbers[1],
                   form="calculix")
    elif kind == "TABULAR" and len(numbers) >= 4:
        rows = [list(numbers[k:k + 2]) for k in range(0, len(numbers) - 1, 2)]
        law.update(normal="tabular", table=rows)
    elif kind not in (None, "HARD", "TIED"):
        raise InputError(f"{record.where or where}: *SURFACE BEHAVIOR, "
                         f"PRESSURE-OVERCLOSURE={kind} of interaction {record.name!r} lacks "
                         f"its values; give them on the data line")
    if record.stick_slope:
        law.update(tangential="elastic", tangential_stiffness=record.stick_slope)
    return law or None


@dataclass(frozen=True)
class SurfaceInteraction:
    """A ``*SURFACE INTERACTION`` as the deck gives it: ``mu``, the stick slope (the
    tangential penalty of ``*FRICTION``, force per length^3) and the ``*SURFACE
    BEHAVIOR`` law (``pressure_overclosure``: HARD, LINEAR, EXPONENTIAL, TABULAR, TIED;
    ``behavior``: the numbers of its data lines), which :func:`law_table` turns into the
    interface's law."""

    name: str
    mu: float | None = None
    stick_slope: float | None = None
    pressure_overclosure: str | None = None
    behavior: tuple = ()
    where: str = ""


@dataclass(frozen=True)
class DeckInterface:
    """A ``*CONTACT PAIR`` as read: surfaces, their bodies, its interaction."""

    slave: str
    master: str
    slave_body: str
    master_body: str
    interaction: SurfaceInteraction | None
    where: str


@dataclass(frozen=True, eq=False)
class Deck:
    """A deck read as a QSMA run.

    Attributes
    ----------
    source : the deck
    config : the configuration, as :func:`qsma.config.parse_config` takes it (mesh paths
        relative to the deck's folder)
    comments : ``{key path: comment}`` of the configuration (where each value came from),
        for :func:`deck_toml`
    notes : :class:`DeckNote` of everything not used
    interfaces : :class:`DeckInterface` per interface of ``config``
    frequency_modes : modes asked for by the ``*FREQUENCY`` step (None: no such step)
    """

    source: Path
    config: dict
    comments: dict
    notes: tuple
    interfaces: tuple
    frequency_modes: int | None

    @property
    def refusals(self) -> tuple:
        return tuple(n for n in self.notes if n.refuses)


@dataclass
class _Material:
    name: str
    where: str
    elastic: tuple | None = None     # (E, nu, where)
    rho: float | None = None


@dataclass
class _Step:
    index: int
    where: str
    procedure: str | None = None
    data: list = field(default_factory=list)    # first data tokens of the procedure
    cards: list = field(default_factory=list)
    nlgeom: bool = False


def _where(card) -> str:
    return _row_where(card.where)


def _row_where(where) -> str:
    """``file, line N``, the file by its name (a deck and the files it includes lie in
    one folder)."""
    return f"{Path(where[0]).name}, line {where[1]}"


def _number(token, where, what) -> float:
    try:
        return _abaqus_float(token)
    except ValueError:
        raise InputError(f"{_row_where(where)}: cannot read {what} {token!r}; give a "
                         f"number") from None


def _spelling(asm, name):
    """The surface's name as the file defines it (Abaqus names ignore case)."""
    for pair in asm.contact_pairs:
        for n in (pair.slave, pair.master):
            if n.upper() == name.upper():
                return n
    return name


def _rows_of(card):
    return _rows(card)


def _loads_in(step) -> bool:
    """Whether a step loads or moves the structure (a ``*BOUNDARY, FIXED`` holds what
    the step before left, e.g. a bolt locked after its pretension)."""
    return any(c.keyword in ("CLOAD", "DLOAD", "DSLOAD", "BOUNDARY")
               and "FIXED" not in c.params for c in step.cards)


#: procedure keywords that open a step
_PROCEDURES = {"STATIC", "FREQUENCY", "DYNAMIC", "HEAT TRANSFER", "BUCKLE", "VISCO",
               "COUPLED TEMPERATURE-DISPLACEMENT", "MODAL DYNAMIC", "STEADY STATE DYNAMICS",
               "COMPLEX FREQUENCY", "UNCOUPLED TEMPERATURE-DISPLACEMENT", "GREEN",
               "SENSITIVITY", "ELECTROMAGNETICS", "CFD"}
#: keywords read by :class:`_DeckReader` itself
_USED = {"MATERIAL", "SOLID SECTION", "BOUNDARY", "CLOAD", "DLOAD", "DSLOAD",
         "CONTACT PAIR", "SURFACE INTERACTION", "STEP", "TIE"} | _MATERIAL_KEYWORDS \
    | _INTERACTION_KEYWORDS
