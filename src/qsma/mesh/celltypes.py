"""Everything qsma knows about a cell type, on one record per type.

A :class:`CellType` holds what the mesh, the readers and writers, the validity checks
and the element assembly need to know about one type: its nodes and reference cell,
its facets, its higher-order nodes, its scikit-fem element, and its names in Gmsh and
Abaqus files. The modules that use these facts read them from :data:`TYPES`, so a new
cell type is one record here (plus, where its geometry needs it, a rule of its own in
the module concerned: the Lagrange geometry of serendipity cells in
:mod:`qsma.fe.elements`).

Names and node order are meshio's (those of VTK): corner nodes first, then the
midside nodes of the edges, then face and body centres. The reference cells are
scikit-fem's and VTK's: ``[-1, 1]^d`` for quadrilaterals and hexahedra, the unit
simplex for triangles and tetrahedra.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["CellType", "TYPES", "CELL_TYPES", "cell_type", "reference_nodes",
           "abaqus_faces", "abaqus_element_types"]


@dataclass(frozen=True)
class CellType:
    """One element type: its topology, reference cell and names in other programs.

    Attributes
    ----------
    name : str
        meshio (and VTK) name, e.g. ``"quad8"``; the key of :data:`TYPES`.
    dim : int
        Topological dimension: 0 (vertex), 1 (lines), 2 (triangles, quadrilaterals),
        3 (solids).
    n_nodes : int
        Nodes per cell.
    linear : str
        The type of its corner nodes (itself for a linear type).
    higher_nodes : tuple of tuples
        For every node after the corners, the corners whose mean it is, in node order
        (VTK: "vtkQuadraticQuad", "vtkBiQuadraticQuad", "vtkQuadraticHexahedron",
        ...); the readers derive their permutations from it.
    facet_type : str or None
        Type of the facets of a cell; None for types that are never the cells of a
        mesh (vertices and lines only carry sets).
    facets : tuple of tuples
        Local nodes of each facet, corners first (counter-clockwise seen from outside
        in 3D), then the facet's midside nodes in the facet type's own order.
    reference : tuple of tuples
        Reference coordinates of the corners (linear types); other types take their
        linear type's (:func:`reference_nodes`).
    basis : tuple of tuples
        Exponents of the monomials that span the shape functions (serendipity cells:
        degree <= 2 in each coordinate with at most one squared coordinate).
    skfem : tuple or None
        ``(mesh class, element class, quadrature order)`` of scikit-fem, by name.
        Orders: 2 is 2x2 (2x2x2) Gauss and a 3-point (4-point) simplex rule, exact for
        the P1/Q1 stiffness and mass; 4 is 3x3 (3x3x3) Gauss and a 6-point (11-point)
        rule, exact for the mass of quadratic cells with straight edges.
    skfem_nodes : tuple or None
        Local node order of scikit-fem where it differs from meshio's (hexahedra):
        scikit-fem node k is meshio node ``skfem_nodes[k]``.
    skfem_geometry : str or None
        The type whose nodes give scikit-fem the geometry when it is not this one:
        serendipity cells are given as the Lagrange cell, whose extra nodes follow
        from the serendipity map (:func:`qsma.fe.elements.lagrange_geometry`).
    description, integration : str or None
        The element family and its full-integration rule, as run reports name them.
    reduced : tuple or None
        ``(scikit-fem quadrature order, rule name)`` of the reduced-integration variant
        (Abaqus suffix R) where qsma computes one: the quadratic quadrilaterals and
        hexahedra on 2x2 (2x2x2) Gauss, whose few zero-energy modes do not spread
        through a mesh; None: refused (linear cells need hourglass control).
    incompatible_modes : bool
        Whether a Wilson-Taylor incompatible-mode variant (``CPE4I``, ``C3D8I``) exists.
    gmsh : int or None
        Gmsh element type number.
    gmsh_higher_nodes : tuple or None
        Gmsh's order of the nodes after the corners where it differs from meshio's
        (Gmsh reference manual, "Node ordering"), as corner groups.
    abaqus : tuple of str
        Abaqus/CalculiX element names read as this type, without the letters R, I, H,
        T that mark reduced integration, incompatible modes, hybrid and coupled
        variants. Continuum names (C3D, CPE, CPS, CAX) give cells; shell, membrane,
        rigid, surface, truss and beam names only carry sets. Abaqus lists the nodes
        as meshio does (linear types; C3D20: 9-12 bottom edges 1-2..4-1, 13-16 top
        edges, 17-20 edges 1-5..4-8; C3D10: 5-10 on edges 1-2, 2-3, 3-1, 1-4, 2-4,
        3-4), so its rows need no reordering.
    abaqus_write : str or None
        Element name written to ``.inp`` files when the mesh names none (plane strain
        in 2D); None: the type cannot be written to an ``.inp`` file.
    abaqus_faces : tuple of tuples
        Abaqus face numbering of linear types: face ``S<k>`` is entry ``k - 1``
        (0-based local nodes, from the Abaqus element library: "face 1: 1-2-3-4, face
        2: 5-8-7-6, face 3: 1-5-6-2, ..." for C3D8; "1-2-3, 1-4-2, 2-4-3, 3-4-1" for
        C3D4; edges 1-2, 2-3, 3-4, 4-1 for CPE4). Quadratic types: :func:`abaqus_faces`.
    """

    name: str
    dim: int
    n_nodes: int
    linear: str
    higher_nodes: tuple = ()
    facet_type: str | None = None
    facets: tuple = ()
    reference: tuple = ()
    basis: tuple = ()
    skfem: tuple | None = None
    skfem_nodes: tuple | None = None
    skfem_geometry: str | None = None
    description: str | None = None
    integration: str | None = None
    reduced: tuple | None = None
    incompatible_modes: bool = False
    gmsh: int | None = None
    gmsh_higher_nodes: tuple | None = None
    abaqus: tuple = ()
    abaqus_write: str | None = None
    abaqus_faces: tuple = ()

    def __post_init__(self):
        if self.n_nodes != self.corners + len(self.higher_nodes):
            raise AssertionError(f"{self.name}: {self.n_nodes} nodes, {self.corners} "
                                 f"corners and {len(self.higher_nodes)} higher nodes")
        if self.basis and len(self.basis) != self.n_nodes:
            raise AssertionError(f"{self.name}: {len(self.basis)} monomials for "
                                 f"{self.n_nodes} nodes")

    @property
    def corners(self) -> int:
        """Corner nodes per cell (the first nodes of a cell row)."""
        return self.n_nodes - len(self.higher_nodes)

    @property
    def is_linear(self) -> bool:
        return self.linear == self.name

    @property
    def is_cell(self) -> bool:
        """Whether a mesh may be made of cells of this type."""
        return self.facet_type is not None

    @property
    def nodes_per_facet(self) -> int:
        return TYPES[self.facet_type].n_nodes


# --------------------------------------------------------------------------------------
# the records

_QUAD_EDGES = ((0, 1), (1, 2), (2, 3), (3, 0))
_HEX_EDGES = ((0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
              (0, 4), (1, 5), (2, 6), (3, 7))
#: VTK face-centre order of the 27-node hexahedron: x-, x+, y-, y+, z-, z+, then the centre
_HEX_FACES = ((0, 3, 7, 4), (1, 2, 6, 5), (0, 1, 5, 4), (3, 2, 6, 7), (0, 1, 2, 3),
              (4, 5, 6, 7), tuple(range(8)))
_TET_EDGES = ((0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3))
#: meshio -> scikit-fem local node order of hexahedra (skfem.io.meshio HEX_MAPPING
#: inverse); the 8- and 20-node hexahedra take its first nodes
_SKFEM_HEX = (0, 4, 3, 1, 7, 5, 2, 6, 16, 11, 8, 15, 12, 19, 10, 17, 9, 14, 13, 18,
              20, 24, 22, 23, 25, 21, 26)
_GMSH_HEX_EDGES = ((0, 1), (0, 3), (0, 4), (1, 2), (1, 5), (2, 3), (2, 6), (3, 7),
                   (4, 5), (4, 7), (5, 6), (6, 7))


def _monomials(d, most, squares=None):
    """Exponents of the monomials in ``d`` coordinates of degree <= ``most`` in each
    coordinate, with at most ``squares`` squared coordinates (None: any)."""
    return tuple(e for e in itertools.product(range(most + 1), repeat=d)
                 if squares is None or e.count(2) <= squares)


def _complete(d, degree):
    """Exponents of the complete polynomial of ``degree`` in ``d`` coordinates."""
    return tuple(e for e in itertools.product(range(degree + 1), repeat=d)
                 if sum(e) <= degree)


_TRIANGLE_BASIS = ((0, 0), (1, 0), (0, 1))
_TETRA_BASIS = ((0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1))


#: quadrilateral monomials in the order of the facet shape functions
_QUAD_BASIS = ((0, 0), (1, 0), (0, 1), (1, 1))
_QUAD2_BASIS = _QUAD_BASIS + ((2, 0), (0, 2), (2, 1), (1, 2))

_RECORDS = (
    CellType("vertex", 0, 1, "vertex", gmsh=15),
    CellType("line", 1, 2, "line", reference=((-1,), (1,)), basis=((0,), (1,)), gmsh=1,
             abaqus=("T2D2", "T3D2", "B21", "B31", "R2D2")),
    CellType("line3", 1, 3, "line", higher_nodes=((0, 1),), basis=((0,), (1,), (2,)),
             gmsh=8, abaqus=("T2D3", "T3D3", "B22", "B32")),
    CellType("triangle", 2, 3, "triangle", facet_type="line",
             facets=((0, 1), (1, 2), (2, 0)),
             reference=((0, 0), (1, 0), (0, 1)), basis=_TRIANGLE_BASIS,
             skfem=("MeshTri1", "ElementTriP1", 2),
             description="3-node triangle (linear)", integration="3-point rule", gmsh=2,
             abaqus=("CPE3", "CPS3", "CAX3", "CPEG3", "S3", "M3D3", "R3D3", "SFM3D3"),
             abaqus_write="CPE3", abaqus_faces=((0, 1), (1, 2), (2, 0))),
    CellType("quad", 2, 4, "quad", facet_type="line",
             facets=((0, 1), (1, 2), (2, 3), (3, 0)),
             reference=((-1, -1), (1, -1), (1, 1), (-1, 1)), basis=_QUAD_BASIS,
             skfem=("MeshQuad1", "ElementQuad1", 2),
             description="4-node quadrilateral (bilinear)", integration="2x2 Gauss",
             incompatible_modes=True, gmsh=3,
             abaqus=("CPE4", "CPS4", "CAX4", "CPEG4", "S4", "M3D4", "R3D4", "SFM3D4"),
             abaqus_write="CPE4", abaqus_faces=((0, 1), (1, 2), (2, 3), (3, 0))),
    CellType("tetra", 3, 4, "tetra", facet_type="triangle",
             facets=((0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)),
             reference=((0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)),
             basis=_TETRA_BASIS,
             skfem=("MeshTet1", "ElementTetP1", 2),
             description="4-node tetrahedron (linear)", integration="4-point rule", gmsh=4,
             abaqus=("C3D4",), abaqus_write="C3D4",
             abaqus_faces=((0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0))),
    CellType("hexahedron", 3, 8, "hexahedron", facet_type="quad",
             facets=((0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4),
                     (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)),
             reference=((-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1),
                        (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)),
             basis=_monomials(3, 1), skfem=("MeshHex1", "ElementHex1", 2),
             skfem_nodes=_SKFEM_HEX[:8],
             description="8-node hexahedron (trilinear)", integration="2x2x2 Gauss",
             incompatible_modes=True, gmsh=5, abaqus=("C3D8",), abaqus_write="C3D8",
             abaqus_faces=((0, 1, 2, 3), (4, 7, 6, 5), (0, 4, 5, 1), (1, 5, 6, 2),
                           (2, 6, 7, 3), (3, 7, 4, 0))),
    CellType("triangle6", 2, 6, "triangle", higher_nodes=((0, 1), (1, 2), (2, 0)),
             facet_type="line3", facets=((0, 1, 3), (1, 2, 4), (2, 0, 5)),
             basis=_TRIANGLE_BASIS + ((2, 0), (1, 1), (0, 2)),
             skfem=("MeshTri2", "ElementTriP2", 4),
             description="6-node triangle (quadratic)", integration="6-point rule", gmsh=9,
             abaqus=("CPE6", "CPS6", "CAX6", "S6", "M3D6", "SFM3D6"), abaqus_write="CPE6"),
    CellType("quad8", 2, 8, "quad", higher_nodes=_QUAD_EDGES, facet_type="line3",
             facets=((0, 1, 4), (1, 2, 5), (2, 3, 6), (3, 0, 7)),
             basis=_QUAD2_BASIS, skfem=("MeshQuad2", "ElementQuadS2", 4),
             skfem_geometry="quad9",
             description="8-node quadrilateral (serendipity)", integration="3x3 Gauss",
             reduced=(2, "2x2 Gauss"),
             gmsh=16, abaqus=("CPE8", "CPS8", "CAX8", "S8", "M3D8", "SFM3D8"),
             abaqus_write="CPE8"),
    CellType("quad9", 2, 9, "quad", higher_nodes=_QUAD_EDGES + ((0, 1, 2, 3),),
             facet_type="line3", facets=((0, 1, 4), (1, 2, 5), (2, 3, 6), (3, 0, 7)),
             basis=_QUAD2_BASIS + ((2, 2),), skfem=("MeshQuad2", "ElementQuad2", 4),
             description="9-node quadrilateral (biquadratic Lagrange)",
             integration="3x3 Gauss", gmsh=10, abaqus=("M3D9",)),
    # tetra10 edges: 4 (0,1), 5 (1,2), 6 (0,2), 7 (0,3), 8 (1,3), 9 (2,3)
    CellType("tetra10", 3, 10, "tetra", higher_nodes=_TET_EDGES, facet_type="triangle6",
             facets=((0, 2, 1, 6, 5, 4), (0, 1, 3, 4, 8, 7), (1, 2, 3, 5, 9, 8),
                     (0, 3, 2, 7, 9, 6)),
             basis=_complete(3, 2), skfem=("MeshTet2", "ElementTetP2", 4),
             description="10-node tetrahedron (quadratic)", integration="11-point rule",
             gmsh=11, gmsh_higher_nodes=((0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1)),
             abaqus=("C3D10", "C3D10M"), abaqus_write="C3D10"),
    # hexahedron20 edges: 8 (0,1), 9 (1,2), 10 (2,3), 11 (3,0), 12 (4,5), 13 (5,6),
    # 14 (6,7), 15 (7,4), 16 (0,4), 17 (1,5), 18 (2,6), 19 (3,7)
    CellType("hexahedron20", 3, 20, "hexahedron", higher_nodes=_HEX_EDGES,
             facet_type="quad8",
             facets=((0, 3, 2, 1, 11, 10, 9, 8), (4, 5, 6, 7, 12, 13, 14, 15),
                     (0, 1, 5, 4, 8, 17, 12, 16), (1, 2, 6, 5, 9, 18, 13, 17),
                     (2, 3, 7, 6, 10, 19, 14, 18), (3, 0, 4, 7, 11, 16, 15, 19)),
             basis=_monomials(3, 2, squares=1), skfem=("MeshHex2", "ElementHexS2", 4),
             skfem_nodes=_SKFEM_HEX[:20], skfem_geometry="hexahedron27",
             description="20-node hexahedron (serendipity)", integration="3x3x3 Gauss",
             reduced=(2, "2x2x2 Gauss"),
             gmsh=17, gmsh_higher_nodes=_GMSH_HEX_EDGES, abaqus=("C3D20",),
             abaqus_write="C3D20"),
    # hexahedron27 face centres: 20 (x-), 21 (x+), 22 (y-), 23 (y+), 24 (z-), 25 (z+)
    CellType("hexahedron27", 3, 27, "hexahedron", higher_nodes=_HEX_EDGES + _HEX_FACES,
             facet_type="quad9",
             facets=((0, 3, 2, 1, 11, 10, 9, 8, 24), (4, 5, 6, 7, 12, 13, 14, 15, 25),
                     (0, 1, 5, 4, 8, 17, 12, 16, 22), (1, 2, 6, 5, 9, 18, 13, 17, 21),
                     (2, 3, 7, 6, 10, 19, 14, 18, 23), (3, 0, 4, 7, 11, 16, 15, 19, 20)),
             basis=_monomials(3, 2), skfem=("MeshHex2", "ElementHex2", 4),
             skfem_nodes=_SKFEM_HEX,
             description="27-node hexahedron (triquadratic Lagrange)",
             integration="3x3x3 Gauss", gmsh=12,
             gmsh_higher_nodes=_GMSH_HEX_EDGES + (
                 (0, 3, 2, 1), (0, 1, 5, 4), (0, 4, 7, 3), (1, 2, 6, 5), (2, 3, 7, 6),
                 (4, 5, 6, 7), tuple(range(8)))),
)

#: every type qsma knows by name: the cells of meshes and the facet, line and vertex
#: elements that carry sets in mesh files
TYPES = {t.name: t for t in _RECORDS}
#: the types a mesh may be made of (those with facets)
CELL_TYPES = {name: t for name, t in TYPES.items() if t.is_cell}


def cell_type(name: str) -> CellType:
    """The record of the cell type ``name`` (a type a mesh may be made of)."""
    found = CELL_TYPES.get(name)
    if found is None:
        raise InputError(f"unsupported cell type {name!r}; expected one of "
                         f"{sorted(CELL_TYPES)}")
    return found


def reference_nodes(name: str) -> np.ndarray:
    """Reference coordinates ``(n_nodes, dim)`` of every node of type ``name``: the
    corners of its linear type, then each further node at the mean of its corners."""
    t = TYPES[name]
    corners = np.array(TYPES[t.linear].reference, dtype=float)
    return np.vstack([corners] + [corners[list(g)].mean(axis=0) for g in t.higher_nodes])


def abaqus_faces(name: str) -> tuple:
    """Local nodes of face ``S<k>`` (entry k - 1) of cells of type ``name``: the corners
    of the linear type's :attr:`CellType.abaqus_faces`, then the cell's further nodes
    that lie on that face."""
    t = TYPES[name]
    if t.is_linear:
        return t.abaqus_faces
    nc = t.corners
    return tuple(tuple(face) + tuple(nc + i for i, g in enumerate(t.higher_nodes)
                                     if set(g) <= set(face))
                 for face in TYPES[t.linear].abaqus_faces)


def outward_abaqus_faces(name: str) -> tuple:
    """The faces ``S<k>`` of :func:`abaqus_faces`, each as the entry of
    :attr:`CellType.facets` with its nodes: corners counter-clockwise seen from outside
    the cell (the orientation of an internal face seen from the cell that owns it)."""
    facets = TYPES[name].facets
    return tuple(next(f for f in facets if set(f) == set(face)) for face in abaqus_faces(name))


def abaqus_element_types() -> dict:
    """Abaqus/CalculiX element name (without variant letters) -> meshio type."""
    return {name: t.name for t in _RECORDS for name in t.abaqus}
