"""The configuration of a mesh file with physical groups (``qsma init model.msh``):
what the mesh says spelled out, what it cannot say marked REQUIRED.

A mesh gives the bodies (its cell sets, or its connected parts), the sets of each
body and the surfaces of two bodies that face each other (the candidate
interfaces). It says nothing of the materials, the friction, the supports, the
loads or the probe: those lines are written commented out and marked, so the file
refuses to run (a missing key is named) until the user has decided each of them; a
value qsma guessed would be a wrong answer nobody chose.
"""
from __future__ import annotations

from pathlib import Path
import re

import numpy as np
from scipy.spatial import cKDTree

from ..mesh.facets import facet_normals
from ..mesh.io.assembly import read_assembly
from ..mesh.touching import touching_facets
from ..version import __version__
from .records import DEFAULT_LEVELS
from .toml import _toml

#: Two facets face each other when their outward normals are opposite to within this
#: cosine and their centroids lie closer than this share of the larger facet's size.
FACING_COS, FACING_DISTANCE = -0.9, 0.75
#: Share of the area of the smaller of two surfaces that must face the other for the
#: pair to be proposed as an interface.
FACING_SHARE = 0.5
#: Set names that suggest a support or a preload (only for the comments written).
_CLAMP_NAMES = re.compile(r"clamp|fix|support|encastre|bc|ground|base", re.I)
_LOAD_NAMES = re.compile(r"bolt|washer|pressure|load|nut|head|preload", re.I)


def mesh_toml(path, folder=None) -> str:
    """The TOML skeleton of the mesh file ``path`` (module docstring); mesh paths
    relative to ``folder`` (default: the mesh's folder)."""
    path = Path(path)
    asm = read_assembly(path)
    names, meshes, how = _bodies(asm)
    rel = _relative(path, folder)
    interfaces = facing_surfaces(names, meshes)
    x = asm.file_mesh.points
    size = float(np.linalg.norm(x.max(axis=0) - x.min(axis=0)))
    dim = meshes[0].dim
    out = [f"# qsma configuration of the mesh {path.name}, written by `qsma init` "
           f"(qsma {__version__}).",
           "# The mesh gave the bodies, their sets and the surfaces that face each other.",
           "# What a mesh cannot give is marked REQUIRED and commented out: decide each,",
           "# remove its '#', then run `qsma run` on this file (until then it refuses to",
           "# run and names the first key missing). Every key: docs/config.md.",
           "", f"name = {_toml(path.stem)}",
           "units = \"SI\"                   # CHOOSE: \"SI\" or \"mm-N-s-tonne\" "
           "(the mesh's coordinates are in its length unit)"]
    for name, mesh, source in zip(names, meshes, how):
        out += ["", "[[bodies]]", f"name = {_toml(name)}", f"mesh = {_toml(rel)}",
                f"{source[0]} = {_toml(source[1])}{' ' * 8}# {source[2]}, "
                f"{mesh.n_cells} {mesh.cell_type} cells",
                "# E = 2.0e11                    # REQUIRED: Young's modulus",
                "# nu = 0.3                      # REQUIRED: Poisson's ratio",
                "# rho = 7850.0                  # REQUIRED: density (a frequency needs "
                "mass)"]
        facets = sorted(mesh.facet_sets)
        nodes = sorted(set(mesh.node_sets) - set(facets))
        out.append(f"# facet sets: {_listing(facets, mesh.facet_sets)}")
        if nodes:
            out.append(f"# node sets: {_listing(nodes, mesh.node_sets)}")
        sets = facets + nodes
        clamp = next((s for s in sets if _CLAMP_NAMES.search(s)), sets[0] if sets else "SET")
        dofs = list(range(1, dim + 1))
        out.append(f"# clamps = [{{ set = {_toml(clamp)}, dofs = {_toml(dofs)} }}]"
                   f"   # REQUIRED unless the joint alone holds the body")
        load = next((s for s in facets if _LOAD_NAMES.search(s)), None)
        if load is not None:
            out.append(f"# pressures = [{{ set = {_toml(load)}, p = 0.0 }}]   # the "
                       f"preload (bolt pressure), guessed from the set's name")
    out += _interface_lines(interfaces, [] if interfaces else _touching_pairs(names, meshes))
    out += ["", "[tip]   # REQUIRED: the probe whose displacement measures the amplitude",
            f"# points = [[{_toml(names[0])}, {_toml([0.0] * dim)}]]   # REQUIRED: a body "
            f"and a point (its nearest node is the probe)",
            f"# direction = {_toml([1.0] + [0.0] * (dim - 1))}      # REQUIRED"]
    lo, hi, n = DEFAULT_LEVELS
    out += ["", f"[levels]   # the probe's linear deflection from {lo:g} to {hi:g} of the "
            f"model's size {size:.6g}",
            "kind = \"tip\"", "spacing = \"log\"", f"start = {_toml(lo * size)}",
            f"stop = {_toml(hi * size)}", f"n = {n}"]
    return "\n".join(out) + "\n"


def _bodies(asm):
    """``(names, meshes, how)``: one body per cell set of the mesh's dimension, or per
    connected part where the file has fewer than two such sets; ``how``: the TOML key,
    its value and where it came from."""
    sets = asm.cell_sets
    if len(sets) >= 2:
        return (list(sets), [asm.body_mesh(s) for s in sets],
                [("cells", s, "the cell set (physical group) of the body")
                 for s in sets])
    parts = asm.components()
    meshes = asm.component_meshes()
    return ([f"part{k + 1}" for k in range(len(parts))], list(meshes),
            [("part", k + 1, f"connected part {k + 1} of the mesh")
             for k in range(len(parts))])


def _listing(names, sets) -> str:
    return ", ".join(f"{n} ({len(sets[n])})" for n in names) or "none"


def _relative(path, folder):
    if folder is None:
        return path.name
    try:
        return str(path.resolve().relative_to(Path(folder).resolve()))
    except ValueError:
        return str(path.resolve())


def facing_surfaces(names, meshes) -> list:
    """The pairs of facet sets of two bodies that face each other: ``(body a, set a,
    body b, set b, share, facets a, facets b, share of the larger)`` with ``share`` the
    part of the smaller surface's area that faces the other (at least
    :data:`FACING_SHARE`), best first, each surface in one pair. Facets face when
    their outward normals are opposite (:data:`FACING_COS`) and their centroids lie
    within :data:`FACING_DISTANCE` of the larger facet's size of each other."""
    surfaces, keys = [], {}
    for name, mesh in zip(names, meshes):
        for set_name, facets in mesh.facet_sets.items():
            if len(facets):
                surfaces.append((name, set_name, _facet_geometry(mesh, facets)))
                keys[name, set_name] = {tuple(sorted(f)) for f in facets.tolist()}
    found = []
    for i, (na, sa, ga) in enumerate(surfaces):
        for nb, sb, gb in surfaces[i + 1:]:
            if na == nb:
                continue
            small, large = sorted((ga, gb), key=lambda g: g[3].sum())
            share = _facing_share(small, large)
            if share >= FACING_SHARE:
                found.append((na, sa, nb, sb, share, len(ga[0]), len(gb[0]),
                              _facing_share(large, small)))
    # best first: the smaller surface facing most, then the larger one (a surface that
    # holds the contact face and more, such as a whole boundary, comes after the face)
    found.sort(key=lambda f: (-f[4], -f[7]))
    used, out = {}, []           # body -> facets in an interface already
    for f in found:              # each facet in one interface: the best facing one
        a, b = keys[f[0], f[1]], keys[f[2], f[3]]
        if a & used.get(f[0], set()) or b & used.get(f[2], set()):
            continue
        used[f[0]] = used.get(f[0], set()) | a
        used[f[2]] = used.get(f[2], set()) | b
        out.append(f)
    return out


def _facet_geometry(mesh, facets):
    """``(centroids, unit outward normals, sizes, areas)`` of ``facets``."""
    n = facet_normals(mesh, facets)
    area = np.linalg.norm(n, axis=1)
    corners = mesh.points[facets]
    centroid = corners.mean(axis=1)
    size = area if mesh.dim == 2 else np.sqrt(area)
    return centroid, n / np.maximum(area, np.finfo(float).tiny)[:, None], size, area


def _facing_share(ga, gb) -> float:
    """The share of surface a's area whose facets face a facet of surface b."""
    ca, na, ha, aa = ga
    cb, nb, hb, _ = gb
    k = min(4, len(cb))
    dist, idx = cKDTree(cb).query(ca, k=k)
    dist, idx = dist.reshape(len(ca), k), idx.reshape(len(ca), k)
    near = dist <= FACING_DISTANCE * np.maximum(ha[:, None], hb[idx])
    opposite = np.einsum("ij,ikj->ik", na, nb[idx]) <= FACING_COS
    facing = np.any(near & opposite, axis=1)
    return float(aa[facing].sum() / aa.sum())


def _touching_pairs(names, meshes) -> list:
    """``(name a, name b, facets of a, facets of b)`` of the bodies that touch
    (:func:`qsma.mesh.touching.touching_facets`), for a mesh whose named surfaces face
    none of another body's."""
    out = []
    for i in range(len(meshes)):
        for j in range(i + 1, len(meshes)):
            fa, fb = touching_facets(meshes[i], meshes[j])
            if len(fa) and len(fb):
                out.append((names[i], names[j], len(fa), len(fb)))
    return out


def _interface_lines(interfaces, touching=()) -> list:
    """The ``[[interfaces]]`` tables of the facing surfaces, mu REQUIRED; without any,
    those of the bodies that touch (``touching = true``)."""
    if not interfaces and touching:
        out = ["", "# No named surfaces of two bodies face each other; these bodies touch:",
               "# qsma finds the faces where they do (touching = true; or name them as",
               "# physical groups and give set1, set2)."]
        for na, nb, fa, fb in touching:
            out += ["", f"[[interfaces]]   # {na} and {nb} touch over {fa} and {fb} facets",
                    f"body1 = {_toml(na)}", f"body2 = {_toml(nb)}", "touching = true",
                    "# mu = 0.6                      # REQUIRED: friction coefficient",
                    "coupling = \"auto\"             # node-to-node where the nodes "
                    "coincide, else mortar"]
        return out
    if not interfaces:
        return ["", "# No two surfaces of different bodies face each other in the mesh:",
                "# define the contact surfaces as physical groups (facet sets) of each body.",
                "# [[interfaces]]",
                "# body1 = \"...\"  set1 = \"...\"  body2 = \"...\"  set2 = \"...\"  mu = ..."]
    out = []
    for na, sa, nb, sb, share, fa, fb, _ in interfaces:
        # the finer side is the mortar slave where the meshes do not match
        slave = na if fa >= fb else nb
        why = "the finer side" if fa != fb else "either side: as many facets on both"
        out += ["", f"[[interfaces]]   # {sa} of {na} faces {sb} of {nb} "
                    f"({100 * share:.0f} % of the smaller surface)",
                f"body1 = {_toml(na)}", f"set1 = {_toml(sa)}",
                f"body2 = {_toml(nb)}", f"set2 = {_toml(sb)}",
                "# mu = 0.6                      # REQUIRED: friction coefficient",
                f"coupling = \"auto\"             # node-to-node where the nodes coincide, "
                f"else mortar",
                f"slave = {_toml(slave)}{' ' * 8}# {why}"]
    return out
