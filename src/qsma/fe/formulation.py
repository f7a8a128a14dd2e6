"""Element formulations: which element a body is computed with, resolved from the mesh.

A body's formulation is fixed by its mesh: the cell type (meshio name) and
``Mesh.element``, the element name given by the source file (Abaqus/CalculiX names
such as ``CPS4``, ``C3D8I``; ``None`` when the file names none, as Gmsh files do).
Nothing is silently replaced: a name qsma does not implement is refused with a
message, and :attr:`Formulation.label` (copied to ``AssembledBody.formulation``)
says what was computed. A body's ``element`` (:func:`with_element`) computes it with
another element, by name or as the nearest one qsma implements
(:func:`nearest_element`: ``C3D8R`` as ``C3D8I``, ``C3D10M`` as ``C3D10``, ...); a
deck run does so with a note.

Plane stress uses unit thickness, like plane strain uses unit depth: stiffness, mass
and pressure loads are all per metre of thickness, so displacements, frequencies,
mode shapes and contact pressures do not depend on the thickness as long as every
body of the model has the same one (a section thickness in the source file is not
read).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
import re

from ..errors import InputError
from ..mesh.celltypes import CELL_TYPES

KINEMATICS = ("plane strain", "plane stress", "3d")


@dataclass(frozen=True)
class Formulation:
    """The element formulation of one body.

    Attributes
    ----------
    cell_type : meshio cell type of the mesh
    kinematics : ``"plane strain"``, ``"plane stress"`` or ``"3d"``
    incompatible : Wilson-Taylor incompatible modes (``CPE4I``, ``CPS4I``, ``C3D8I``)
    source : element name given by the source file (``None``: none given)
    reduced : the stiffness on the reduced rule of the cell type
        (:attr:`qsma.mesh.celltypes.CellType.reduced`: ``CPE8R``, ``CPS8R``, ``C3D20R``);
        the mass stays consistent (full rule)
    """

    cell_type: str
    kinematics: str
    incompatible: bool = False
    source: str | None = None
    reduced: bool = False

    def __post_init__(self):
        if self.cell_type not in CELL_TYPES:
            raise InputError(f"no element formulation for cell type {self.cell_type!r}")
        if self.kinematics not in KINEMATICS:
            raise InputError(f"kinematics must be one of {KINEMATICS}, got "
                             f"{self.kinematics!r}")
        if self.incompatible and not CELL_TYPES[self.cell_type].incompatible_modes:
            raise InputError(f"incompatible modes exist for 4-node quadrilaterals and "
                             f"8-node hexahedra only, not {self.cell_type!r}")
        if self.reduced and CELL_TYPES[self.cell_type].reduced is None:
            raise InputError(f"reduced integration is computed for 8-node quadrilaterals "
                             f"and 20-node hexahedra only, not {self.cell_type!r}")

    @property
    def name(self) -> str:
        """Abaqus-style name of what is computed (``CPE4I``, ``CPS8``, ``C3D20``; qsma
        writes ``CPE9`` / ``C3D27`` for the 9- and 27-node Lagrange cells)."""
        digits = str(CELL_TYPES[self.cell_type].n_nodes)
        prefix = {"plane strain": "CPE", "plane stress": "CPS", "3d": "C3D"}[self.kinematics]
        return prefix + digits + ("I" if self.incompatible else "") + \
            ("R" if self.reduced else "")

    @property
    def label(self) -> str:
        """One line saying what is computed, e.g. ``"CPE4I: plane strain, 4-node
        quadrilateral (bilinear), incompatible modes (Wilson-Taylor), 2x2 Gauss"``."""
        ct = CELL_TYPES[self.cell_type]
        family, rule = ct.description, ct.integration
        what = "incompatible modes (Wilson-Taylor QM6 with Taylor's correction)" \
            if self.incompatible else "full integration"
        if self.incompatible and self.kinematics == "3d":
            what = "incompatible modes (Wilson-Taylor, 9 modes, Taylor's correction)"
        if self.reduced:
            what, rule = "reduced integration (stiffness; consistent mass)", ct.reduced[1]
        kin = "" if self.kinematics == "3d" else f"{self.kinematics} (unit thickness), "
        return f"{self.name}: {kin}{family}, {what}, {rule}"


@dataclass(frozen=True)
class MixedFormulation:
    """The formulations of the cell blocks of a mixed mesh (one per block, in the
    order of :attr:`qsma.mesh.Mesh.cell_blocks`), all of one kinematics.

    Attributes
    ----------
    parts : tuple of :class:`Formulation`
    """

    parts: tuple

    def __post_init__(self):
        kinds = {p.kinematics for p in self.parts}
        if len(kinds) > 1:
            raise InputError(
                f"the cell blocks of one body use different kinematics ("
                f"{', '.join(p.name + ': ' + p.kinematics for p in self.parts)}); a body "
                f"is plane strain, plane stress or 3D as a whole: use CPE* (or CPS*) "
                f"element names for every block")

    @property
    def kinematics(self) -> str:
        return self.parts[0].kinematics

    @property
    def name(self) -> str:
        """Block names joined, e.g. ``"CPE4I+CPE3"``."""
        return "+".join(p.name for p in self.parts)

    @property
    def label(self) -> str:
        """The labels of the blocks, ``" + "``-joined (what is computed, block by block)."""
        return "mixed mesh: " + " + ".join(p.label for p in self.parts)


def hourglass_hint(assembled) -> str:
    """A sentence for messages about a singular stiffness: the bodies computed with
    reduced integration (their zero-energy modes spread through meshes one element
    thick), or "" if none is."""
    names = [f"{a.body.name!r} ({a.element.name})" for a in assembled
             if getattr(a.element, "reduced", False)]
    if not names:
        return ""
    return (f" Or a zero-energy (hourglass) mode of reduced integration in body "
            f"{', '.join(names)}: use the fully integrated element (without R) or mesh at "
            f"least two elements through every section.")


def resolve_formulations(mesh):
    """:func:`resolve_formulation` of a mesh of one or several cell blocks: a
    :class:`Formulation`, or a :class:`MixedFormulation` for a mixed mesh."""
    if not getattr(mesh, "is_mixed", False):
        return resolve_formulation(mesh)
    return MixedFormulation(tuple(resolve_formulation(m) for m, _ in mesh.block_meshes()))


_ABAQUS = re.compile(r"^(CPE|CPS|CAX|CGAX|C3D)(\d+)([A-Z]*)$")


def resolve_formulation(mesh) -> Formulation:
    """The formulation of a body with mesh ``mesh`` (see the module docstring).

    ``mesh.element`` ``None``: plane strain in 2D, full integration. Otherwise an
    Abaqus/CalculiX name whose node count must match the cell type: ``CPE*`` plane
    strain, ``CPS*`` plane stress, ``C3D*`` solid, suffix ``I`` incompatible modes.
    Suffix ``R`` (reduced integration) for 8-node quadrilaterals and 20-node hexahedra
    (:attr:`qsma.mesh.celltypes.CellType.reduced`). Refused with :class:`InputError`:
    axisymmetric ``CAX*``, reduced integration of other cells, hybrid ``*H`` and other
    suffixes, node-count mismatches.
    """
    ct = mesh.cell_type
    name = getattr(mesh, "element", None)
    dim = mesh.dim
    if name is None:
        return Formulation(ct, "plane strain" if dim == 2 else "3d")
    key = str(name).strip().upper()
    m = _ABAQUS.match(key)
    if m is None:
        raise InputError(f"element type {name!r} is not an element qsma knows; supported: "
                         f"CPE*/CPS* (2D plane strain / stress), C3D* (3D solids), with "
                         f"suffix I for incompatible modes on 4-node quads / 8-node bricks")
    family, digits, suffix = m.groups()
    if family in ("CAX", "CGAX"):
        raise InputError(f"element type {name!r} is axisymmetric; qsma does not implement "
                         f"axisymmetric elements (they would need the hoop strain u_r / r "
                         f"and the 2 pi r weight). Model the joint in 3D, or as plane "
                         f"strain (CPE*) if that is what you mean")
    if (family == "C3D") != (dim == 3):
        raise InputError(f"element type {name!r} does not fit a {dim}D {ct!r} mesh")
    expected = str(CELL_TYPES[ct].n_nodes)
    incompatible = CELL_TYPES[ct].incompatible_modes
    if digits != expected and not (ct == "quad9" and digits == "9"):
        raise InputError(f"element type {name!r} has {digits} nodes but the mesh cells are "
                         f"{ct!r} with {expected}; the mesh and the element name disagree")
    kin = {"CPE": "plane strain", "CPS": "plane stress", "C3D": "3d"}[family]
    if suffix == "R" and CELL_TYPES[ct].reduced is not None:
        return Formulation(ct, kin, False, str(name), reduced=True)
    if suffix == "R":
        raise InputError(
            f"element type {name!r} uses reduced integration, which qsma computes for "
            f"8-node quadrilaterals and 20-node hexahedra only (a linear cell would need "
            f"hourglass control: its zero-energy modes would corrupt the frequencies). "
            f"Use the fully integrated {family}{digits}"
            + (f" or the incompatible-mode {family}{digits}I (bending-accurate)"
               if incompatible else "") + " instead (a TOML body: element = \""
            + (f"{family}{digits}I" if incompatible else f"{family}{digits}") + "\")")
    if suffix not in ("", "I"):
        near = nearest_element(key, ct)
        raise InputError(f"element type {name!r}: suffix {suffix!r} (hybrid, modified, "
                         f"coupled...) is not implemented; use {family}{digits}"
                         + (f" or {family}{digits}I" if incompatible else "")
                         + (f" (a TOML body: element = \"{near[0]}\", or \"nearest\")"
                            if near else ""))
    if suffix == "I" and not incompatible:
        raise InputError(f"element type {name!r}: incompatible modes exist for CPE4I/CPS4I"
                         f"/C3D8I only")
    return Formulation(ct, kin, suffix == "I", source=str(name))


#: Why an element qsma does not implement is computed with its nearest one (what
#: :func:`nearest_element` gives), by the suffix letters dropped or replaced.
_NEAREST_WHY = {
    "R": "reduced integration of a linear cell needs hourglass control, which qsma does "
         "not implement; computed with incompatible modes, the bending-accurate linear "
         "element. On coarse meshes the reduced element of Abaqus/CalculiX is softer: "
         "CalculiX's C3D8R gives lap-3d (two elements through each plate) a first "
         "frequency 12 % below C3D8I, 3 % below with four, where C3D8I has converged "
         "to 0.03 % (docs/validation.md); check the mesh convergence",
    "H": "the hybrid (mixed displacement-pressure) formulation matters for nearly "
         "incompressible materials only; computed with the displacement formulation",
    "M": "the modified quadratic tetrahedron; computed as the standard one (C3D10)",
    "I": "the improved-stress quadratic tetrahedron; computed as the standard one "
         "(C3D10)",
}


def nearest_element(name, cell_type) -> tuple | None:
    """``(element qsma computes, why)`` for an Abaqus/CalculiX element name qsma does
    not implement but whose nearest formulation it does (``C3D8R`` -> ``C3D8I``,
    ``C3D10M`` -> ``C3D10``, ``C3D20RH`` -> ``C3D20R``, ...); None when ``name`` is
    implemented or has no such neighbour (axisymmetric, other suffixes)."""
    m = _ABAQUS.match(str(name).strip().upper()) if name is not None else None
    if m is None or cell_type not in CELL_TYPES:
        return None
    family, digits, suffix = m.groups()
    if family in ("CAX", "CGAX") or not suffix or suffix == "I" and \
            CELL_TYPES[cell_type].incompatible_modes:
        return None
    if suffix == "R" and CELL_TYPES[cell_type].reduced is not None:
        return None
    letters, why = set(suffix), []
    if not letters <= set("RHMI"):
        return None
    keep = ""
    if "R" in letters:
        keep = "R" if CELL_TYPES[cell_type].reduced is not None else \
            "I" if CELL_TYPES[cell_type].incompatible_modes else None
        if keep is None:
            return None
        if keep == "I":
            why.append(_NEAREST_WHY["R"])
    if "I" in letters:
        if CELL_TYPES[cell_type].incompatible_modes:
            keep = "I"
        else:
            why.append(_NEAREST_WHY["I"])
    for letter in "HM":
        if letter in letters:
            why.append(_NEAREST_WHY[letter])
    return f"{family}{digits}{keep}", "; ".join(why)


def with_element(mesh, element: str):
    """``mesh`` computed with ``element`` instead of the element names of its file (a
    body's ``element`` key): an Abaqus/CalculiX name for a mesh of one cell type, or
    ``"nearest"``: each cell block's name replaced by :func:`nearest_element` where
    qsma does not implement it. Checked: :class:`InputError` naming what does not fit."""
    if str(element).strip().lower() == "nearest":
        def nearest(name, cell_type):
            found = nearest_element(name, cell_type)
            return name if found is None else found[0]
        blocks = tuple(replace(b, element=nearest(b.element, b.cell_type))
                       for b in mesh.extra_blocks)
        out = replace(mesh, element=nearest(mesh.element, mesh.cell_type),
                      extra_blocks=blocks)
    elif getattr(mesh, "is_mixed", False):
        raise InputError(f"element = {element!r} names one element for a mesh of several "
                         f"cell types ({', '.join(b.cell_type for b in mesh.cell_blocks)}); "
                         f"give element = \"nearest\" or mesh the body with one cell type")
    else:
        out = replace(mesh, element=str(element).strip())
    resolve_formulations(out)
    return out
