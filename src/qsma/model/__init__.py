"""Finite element models: bodies, materials, supports, loads, bolts, springs, interfaces
and their pairing; the mesh names a model is built with (from :mod:`qsma.mesh`)."""
from ..mesh import CELL_TYPES, FacetIndex, Mesh, boundary_facets, facet_index, validate_mesh
from .body import Material, Clamp, Pressure, NodalForce, Body, Probe, Model
from .interface import Interface, Pairing, pair_nodes, local_frames
from .pairing import make_pairing

__all__ = ["Mesh", "boundary_facets", "CELL_TYPES", "Material", "Clamp", "Pressure",
           "NodalForce",
           "Body", "Probe", "Model", "Interface", "Pairing", "make_pairing", "pair_nodes",
           "local_frames"]

from .bolt import Bolt, SectionBolt  # noqa: E402
from .spring import Spring  # noqa: E402
from .damping import LinearDamping  # noqa: E402
from .gapfield import GapField, read_gap_field  # noqa: E402
from .mass import PointMass  # noqa: E402

__all__ += ["Bolt", "SectionBolt", "Spring", "PointMass", "LinearDamping", "GapField", "read_gap_field",
            "read_mesh", "write_mesh", "FacetIndex", "facet_index", "validate_mesh"]


def __getattr__(name):
    """``read_mesh`` and ``write_mesh`` imported when first used: the mesh readers and
    writers (Abaqus, Gmsh) cost 0.08 s of CPU to import, and a run of a model built in
    memory (``qsma run --example``) never reads a mesh file."""
    if name in ("read_mesh", "write_mesh"):
        from ..mesh import io
        return getattr(io, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
