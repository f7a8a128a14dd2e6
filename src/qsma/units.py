"""Unit systems: what the numbers of a model mean, and the units of every result.

qsma computes in whatever consistent unit system the model is written in; nothing
is converted. The model declares its system (``Model(units=...)``, the TOML key
``units``) so that every label, file and message names the right units: the same
tip deflection is ``1.0e-03 m`` in an SI model and ``1.0 mm`` in a
millimetre-newton-second-tonne model. A model whose material constants look like
another system than the one declared gets a :class:`qsma.errors.UnitSystemWarning`
(:func:`check_model_units`): Young's modulus 2e5 and density 7.85e-9 are steel in
mm-N-s-tonne, and in SI a material a million times softer than rubber and ten
thousand times lighter than air.

A 2D model is computed per unit out-of-plane depth: its forces, masses and energies
are per unit length of depth (``J/m``); :func:`quantity_unit` says so.
"""
from __future__ import annotations

from dataclasses import dataclass
import warnings

from ._infra.deprecation import forward
from .errors import InputError, UnitSystemWarning


@dataclass(frozen=True)
class UnitSystem:
    """A consistent unit system: the units of length, force, time and mass and those
    derived from them, with their factors to SI.

    Attributes
    ----------
    name : the name a model declares (``"SI"``, ``"mm-N-s-tonne"``)
    length, force, time, mass, stress, density, energy : unit names
    length_m, force_n, mass_kg : one unit of length, force, mass in m, N, kg (the
        time unit is the second in every system here, so frequencies are in Hz)
    """

    name: str
    length: str
    force: str
    time: str
    mass: str
    stress: str
    density: str
    energy: str
    length_m: float
    force_n: float
    mass_kg: float

    @property
    def stress_pa(self) -> float:
        """One unit of stress in Pa."""
        return self.force_n / self.length_m ** 2

    @property
    def density_si(self) -> float:
        """One unit of density in kg/m^3."""
        return self.mass_kg / self.length_m ** 3


SI = UnitSystem("SI", "m", "N", "s", "kg", "Pa", "kg/m^3", "J", 1.0, 1.0, 1.0)
#: Millimetre, newton, second, tonne: the system of most engineering FE decks
#: (stress in MPa = N/mm^2, density in t/mm^3, energy in mJ = N mm).
MM_N_S_TONNE = UnitSystem("mm-N-s-tonne", "mm", "N", "s", "t", "MPa", "t/mm^3", "mJ",
                          1e-3, 1.0, 1e3)
#: The unit systems a model may declare, by name.
UNIT_SYSTEMS = {u.name: u for u in (SI, MM_N_S_TONNE)}
DEFAULT = SI.name


def unit_system(units) -> UnitSystem:
    """The :class:`UnitSystem` named ``units`` (a :class:`UnitSystem` is returned as
    it is).

    Raises
    ------
    InputError
        an unknown name, with the valid ones.
    """
    if isinstance(units, UnitSystem):
        return units
    if isinstance(units, str) and units in UNIT_SYSTEMS:
        return UNIT_SYSTEMS[units]
    raise InputError(f"unknown unit system {units!r}; valid: {sorted(UNIT_SYSTEMS)} "
                     f"(SI: m, N, s, kg, Pa; mm-N-s-tonne: mm, N, s, t, MPa). Every "
                     f"number of the model must be in the system declared")


#: The physical quantities of the results and how each is built from the base units;
#: ``per_depth``: a 2D model gives it per unit out-of-plane depth.
QUANTITIES = ("length", "force", "mass", "stress", "density", "energy", "velocity",
              "frequency", "modal_force", "modal_amplitude", "mode_shape", "dimensionless")
_PER_DEPTH = ("force", "mass", "energy", "modal_force", "modal_amplitude", "mode_shape")


def quantity_unit(quantity, units=SI, dim=3, pretty=False) -> str:
    """The unit of ``quantity`` (one of :data:`QUANTITIES`) in ``units``, as text.

    A mass-normalised mode has units of 1/sqrt(mass), so the modal amplitude
    ``q = phi^T M u`` is length * sqrt(mass) and the modal force ``alpha = phi^T f``
    force / sqrt(mass); their product is an energy; the mode shape itself is
    1 / sqrt(mass). In 2D (``dim = 2``) the forces,
    masses and energies are per unit depth (mass per depth ``kg/m``, energy ``J/m``).
    ``pretty``: with the square-root sign for figures (``√kg m``), else ASCII
    (``kg^0.5 m``) for files.
    """
    u = unit_system(units)
    if quantity not in QUANTITIES:
        raise ValueError(f"unknown quantity {quantity!r}; known: {QUANTITIES}")
    depth = dim == 2 and quantity in _PER_DEPTH
    mass = f"{u.mass}/{u.length}" if depth else u.mass
    force = f"{u.force}/{u.length}" if depth else u.force
    root = (lambda m: f"\u221a({m})" if "/" in m else f"\u221a{m}") if pretty else \
        (lambda m: f"({m})^0.5" if "/" in m else f"{m}^0.5")
    return {
        "length": u.length,
        "force": force,
        "mass": mass,
        "stress": u.stress,
        "density": u.density,
        "energy": f"{u.energy}/{u.length}" if depth else u.energy,
        "velocity": f"{u.length}/{u.time}",
        "frequency": "Hz",
        "modal_force": (f"({force})/{root(mass)}" if depth else f"{force}/{root(mass)}"),
        "modal_amplitude": f"{root(mass)} {u.length}",
        "mode_shape": f"1/{root(mass)}",
        "dimensionless": "-",
    }[quantity]


def column_label(name, unit) -> str:
    """A table heading: ``name [unit]``, or the bare name of a field without a unit."""
    return name if unit is None else f"{name} [{unit}]"


def display_stress(units=SI) -> tuple:
    """``(label, factor)`` of contact pressures in figures: always MPa, ``factor``
    turning the model's stress unit into it."""
    return "MPa", unit_system(units).stress_pa / 1e6


# -- Does a model look like its declared system? ------------------------------------------

#: Young's modulus of solids a joint model may hold, in Pa: from soft elastomers
#: (about 1e5 Pa, silicone rubber is 1e6-1e7) to diamond (1.2e12 Pa).
E_RANGE_PA = (1e5, 1.5e12)
#: Density of solids, in kg/m^3: from rigid polymer foams (about 10) to osmium (22,590).
DENSITY_RANGE_SI = (5.0, 3.0e4)


def plausible(material, units) -> bool:
    """Whether ``material``'s E and rho, read in ``units``, lie in the ranges of real
    solids (:data:`E_RANGE_PA`, :data:`DENSITY_RANGE_SI`). The density decides most
    cases: its ranges in SI and in mm-N-s-tonne are twelve decades apart."""
    u = unit_system(units)
    E = material.E * u.stress_pa
    rho = material.rho * u.density_si
    return (E_RANGE_PA[0] <= E <= E_RANGE_PA[1]
            and DENSITY_RANGE_SI[0] <= rho <= DENSITY_RANGE_SI[1])


def unit_mismatches(model) -> list[str]:
    """One sentence per body whose material does not look like the model's declared
    unit system, naming the system it looks like and the fix."""
    declared = unit_system(getattr(model, "units", DEFAULT))
    out = []
    for b in model.bodies:
        m = b.material
        if plausible(m, declared):
            continue
        other = [u for u in UNIT_SYSTEMS.values() if u is not declared and plausible(m, u)]
        what = (f"body {b.name!r}: E = {m.E:g} and rho = {m.rho:g} are not a solid in "
                f"{declared.name} (E in {declared.stress}, rho in {declared.density})")
        if other:
            u = other[0]
            out.append(f"{what}; they look like {u.name} (E in {u.stress}, rho in "
                       f"{u.density}). Declare units = {u.name!r} if the whole model is "
                       f"in {u.name}, or convert the numbers to {declared.name}")
        else:
            out.append(f"{what}, nor in any other system qsma knows "
                       f"({sorted(UNIT_SYSTEMS)}); check E and rho and the units "
                       f"declared")
    return out


def check_model_units(model):
    """Warn (:class:`qsma.errors.UnitSystemWarning`) for each body whose material looks
    like another unit system than the model declares (:func:`unit_mismatches`)."""
    for text in unit_mismatches(model):
        warnings.warn(text, UnitSystemWarning, stacklevel=3)


def to_model_length(metres, units) -> float:
    """``metres`` in the model's length unit."""
    return metres / unit_system(units).length_m


__all__ = ["UnitSystem", "SI", "MM_N_S_TONNE", "UNIT_SYSTEMS", "unit_system",
           "quantity_unit", "column_label", "display_stress", "check_model_units",
           "unit_mismatches"]

# the units of the per-level results moved beside the fields they describe
forward(__name__, names={name: "qsma.analysis.result" for name in
                         ("LEVEL_QUANTITIES", "level_units", "units_block")})

