"""Helpers shared by several test modules (tests import this module, never each
other): patch tests, distorted meshes, a small Abaqus deck, blocks and rings meshed
apart for the mortar tests."""
import dataclasses
import shutil

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from qsma.contact import ContactProblem, solve as contact_solve
from qsma.fe import assemble_body, stress_at_nodes
from qsma.examples import stack_2d
from qsma.modal import stacked, tie_transform
from qsma.model import (Body, Clamp, Interface, Material, Mesh, Model, Pressure,
                        boundary_facets, make_pairing, write_mesh)
from qsma.mesh.generate import structured_mesh
from qsma.reduction.two_bodies import reduce_two_bodies

STEEL = Material(200e9, 0.285, 7800.0)

#: The comparisons with CalculiX run where ``ccx`` is on the path; elsewhere only they
#: are skipped, the rest of each module runs.
needs_ccx = pytest.mark.skipif(shutil.which("ccx") is None,
                               reason="CalculiX (ccx) not installed "
                                      "(apt-get install calculix-ccx)")


def distorted_patch(cell_type):
    """A 4 x 4 unit-square patch of quads (or triangles) with its interior nodes moved
    at random (seeded)."""
    xs = np.linspace(0, 1, 5)
    m = structured_mesh(xs, xs)
    p = m.points.copy()
    rng = np.random.default_rng(0)
    inner = (p[:, 0] > 0) & (p[:, 0] < 1) & (p[:, 1] > 0) & (p[:, 1] < 1)
    p[inner] += rng.uniform(-0.08, 0.08, size=(inner.sum(), 2))
    if cell_type == "quad":
        return Mesh(p, m.cells, "quad")
    tri = np.concatenate([m.cells[:, [0, 1, 2]], m.cells[:, [0, 2, 3]]])
    return Mesh(p, tri, "triangle")


def check_patch(mesh, A):
    """Impose ``u = A x`` on the boundary of ``mesh``: the interior must reproduce it to
    round-off and the stress must be the uniform ``C : sym(A)``."""
    dim = mesh.dim
    a = assemble_body(Body("patch", mesh, STEEL))
    u = (mesh.points @ A.T).ravel()
    bnd = np.unique(boundary_facets(mesh))
    B = (dim * bnd[:, None] + np.arange(dim)).ravel()
    I = np.setdiff1d(np.arange(a.n_dofs), B)
    K = a.K.tocsr()
    uI = spla.spsolve(K[I][:, I].tocsc(), -K[I][:, B] @ u[B])
    assert np.abs(uI - u[I]).max() < 1e-12 * np.abs(u).max()
    sig, _ = stress_at_nodes(a.body, u)
    lam, mu = STEEL.lame
    eps = 0.5 * (A + A.T)
    exact = 2 * mu * eps + lam * np.trace(eps) * np.eye(dim)
    assert np.abs(sig - exact).max() < 1e-9 * np.abs(exact).max()
    return a


# Kuhn split along the 0-6 diagonal: conforming between neighbouring hexahedra
HEX_TO_TETS = [(0, 1, 2, 6), (0, 2, 3, 6), (0, 3, 7, 6), (0, 7, 4, 6), (0, 4, 5, 6), (0, 5, 1, 6)]


def tetrahedra_of(mesh):
    """The hexahedra of ``mesh`` split into six tetrahedra each (:data:`HEX_TO_TETS`,
    conforming between neighbours), every tetrahedron positively oriented; no sets."""
    tets = np.concatenate([mesh.cells[:, list(t)] for t in HEX_TO_TETS])
    q = mesh.points[tets]
    vol = np.einsum("ij,ij->i", np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]),
                    q[:, 3] - q[:, 0])
    tets[vol < 0] = tets[vol < 0][:, [0, 2, 1, 3]]
    return Mesh(mesh.points, tets, "tetra")


def distorted_3d(cell_type):
    """A 3 x 3 x 3 unit-cube patch of hexahedra (or tetrahedra) with its interior nodes
    moved at random (seeded)."""
    xs = np.linspace(0, 1, 4)
    m = structured_mesh(xs, xs, xs)
    p = m.points.copy()
    inner = np.all((p > 0) & (p < 1), axis=1)
    p[inner] += np.random.default_rng(0).uniform(-0.08, 0.08, size=(inner.sum(), 3))
    if cell_type == "hexahedron":
        return Mesh(p, m.cells, "hexahedron")
    return tetrahedra_of(Mesh(p, m.cells, "hexahedron"))


#: Two CPE4 elements with the four surface spellings of Abaqus (S1-S4)
QUAD_GRID = """\
*NODE
1, 0, 0
2, 1, 0
3, 2, 0
4, 0, 1
5, 1, 1
6, 2, 1
*ELEMENT, TYPE=CPE4, ELSET=ALL
1, 1, 2, 5, 4
2, 2, 3, 6, 5
*ELSET, ELSET=_first, INTERNAL
1
*SURFACE, TYPE=ELEMENT, NAME=s1
1, S1
*SURFACE, NAME=s2
2, S2
*Surface, type=element, name=s3
_first, s3
*SURFACE, NAME=s4
_FIRST, S4
"""


#: OpenBLAS kernels on which a multi-RHS SuperLU solve split at even column offsets
#: has the bits of the serial solve (measured: Haswell, SandyBridge, Zen, Prescott);
#: the Nehalem kernel rounds columns in wider groups (~1e-16 apart).
PAIRWISE_KERNELS = ("haswell", "sandybridge", "zen", "prescott")


def scipy_blas_kernel() -> str:
    """The kernel (architecture) of the BLAS that scipy's SuperLU calls, lower case, or
    "" where threadpoolctl does not say."""
    import scipy.sparse.linalg  # noqa: F401  (loads scipy's BLAS)
    from threadpoolctl import threadpool_info
    for info in threadpool_info():
        if "scipy" in info.get("filepath", "") and "numpy" not in info.get("filepath", ""):
            return str(info.get("architecture", "")).lower()
    return ""


def assert_same_solve_bits(a, b, rtol=1e-14):
    """``a`` and ``b`` (computed with threaded and with serial solves) equal bit for bit
    on the kernels of :data:`PAIRWISE_KERNELS`; elsewhere to ``rtol`` of the largest
    entry (the kernel's own rounding of a column depends on its neighbours there, and
    an iterative method built on the solves carries that round-off on)."""
    if scipy_blas_kernel() in PAIRWISE_KERNELS:
        assert np.array_equal(a, b)
    else:
        assert np.abs(np.asarray(a) - np.asarray(b)).max() <= rtol * np.abs(a).max()


def bodies_in_one_mesh(bodies) -> Mesh:
    """The meshes of ``bodies`` as one mesh (nodes of each body kept apart), each body a
    cell set of its name, each set ``<body>_<set>``."""
    pts, cells, node_sets, facet_sets, cell_sets = [], [], {}, {}, {}
    n = c = 0
    for b in bodies:
        m = b.mesh
        pts.append(m.points)
        cells.append(m.cells + n)
        cell_sets[b.name] = np.arange(c, c + len(m.cells))
        node_sets.update({f"{b.name}_{k}": v + n for k, v in m.node_sets.items()})
        facet_sets.update({f"{b.name}_{k}": v + n for k, v in m.facet_sets.items()})
        n += m.n_nodes
        c += len(m.cells)
    return Mesh(np.vstack(pts), np.vstack(cells), bodies[0].mesh.cell_type, node_sets,
                facet_sets, cell_sets)


def one_file(bodies, path):
    """Write the meshes of ``bodies`` as one mesh file (:func:`bodies_in_one_mesh`)."""
    write_mesh(path, bodies_in_one_mesh(bodies))
    return path


def body_toml(name, mesh, pressures=True):
    """The ``[[bodies]]`` table of body ``name``: cell set ``name`` of ``mesh``, steel,
    clamped on ``<name>_clamp``, the bolt pressure on ``<name>_bolt``."""
    text = (f'[[bodies]]\nname = "{name}"\nmesh = "{mesh}"\ncells = "{name}"\n'
            f'E = 200e9\nnu = 0.285\nrho = 6600.0\nclamps = [{{ set = "{name}_clamp" }}]\n')
    if pressures:
        text += f'pressures = [{{ set = "{name}_bolt", p = 17.554e6 }}]\n'
    return text


def stack_toml(tmp_path, interfaces):
    """stack-2d as one Gmsh file and a configuration with ``interfaces`` (TOML text);
    returns the configuration's path and the model it was written from."""
    model = stack_2d(1)
    one_file(model.bodies, tmp_path / "stack.msh")
    text = "".join(body_toml(b.name, "stack.msh", b.name != "middle")
                   for b in model.bodies)
    text += interfaces
    text += ('[tip]\nsets = [["bottom", "bottom_tip"], ["middle", "middle_tip"], '
             '["top", "top_tip"]]\ndirection = [0.0, 1.0]\n')
    (tmp_path / "stack.toml").write_text(text)
    return tmp_path / "stack.toml", model


STACK_INTERFACES = (
    '[[interfaces]]\nbody1 = "bottom"\nset1 = "bottom_upper"\nbody2 = "middle"\n'
    'set2 = "middle_lower"\nmu = 0.6\n'
    '[[interfaces]]\nbody1 = "middle"\nset1 = "middle_upper"\nbody2 = "top"\n'
    'set2 = "top_lower"\nmu = 0.3\n')


def load_benchmark(name):
    """The module ``benchmarks/<name>.py`` (the CalculiX comparisons share their deck
    writers with the tests)."""
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def in_forked_child(function):
    """Run ``function()`` in a forked child and fail the test with the child's traceback
    if it raised. For tests that leave threads behind (a Dask client's IO loop thread
    outlives the client in ``distributed``): they would keep the rest of the session
    from forking (qsma forks only a process with one thread)."""
    import multiprocessing
    import traceback
    import pytest
    ctx = multiprocessing.get_context("fork")
    receive, send = ctx.Pipe(duplex=False)

    def target():
        try:
            function()
            send.send(None)
        except BaseException:               # reported to the parent, the child ends
            send.send(traceback.format_exc())

    child = ctx.Process(target=target)
    child.start()
    send.close()
    try:
        error = receive.recv()
    except EOFError:
        error = f"the child ended without a report (exit code {child.exitcode})"
    child.join()
    if error is not None:
        pytest.fail(error, pytrace=False)


# ------------------------------------------------------------ blocks meshed apart
#: The material of the stacked blocks and rings of the mortar tests
BLOCK_STEEL = Material(200e9, 0.3, 7800.0)
#: Width and height of a stacked block [m] (any size: the answers are exact)
BLOCK_W, BLOCK_H = 0.04, 0.01


def block_sets(m, y0, dim, held):
    """The block mesh ``m`` of ``[0, BLOCK_W] x [y0, y0 + BLOCK_H] (x [0, BLOCK_W])`` with
    its sets (facets ``lower``, ``upper``) and its clamps: ``held`` "bottom" clamps u_y on
    its lower face and u_x (u_z) on edges of that face (no interface node), "top" the
    same on its upper face, "" nothing. Returns ``(mesh, clamps)``."""
    x = m.points
    e = 1e-9 * BLOCK_W
    lo, hi = np.abs(x[:, 1] - y0) < e, np.abs(x[:, 1] - y0 - BLOCK_H) < e
    face = lo if held == "bottom" else hi
    sets = {"yface": np.flatnonzero(face), "xline": np.flatnonzero(face & (x[:, 0] < e))}
    clamps = [Clamp("yface", (1,)), Clamp("xline", (0,))] if held else []
    if dim == 3 and held:
        sets["zline"] = np.flatnonzero(face & (x[:, 2] < e))
        clamps.append(Clamp("zline", (2,)))
    top = y0 + BLOCK_H
    facets = {"lower": m.boundary_facets_where(lambda p: np.abs(p[:, 1] - y0) < e),
              "upper": m.boundary_facets_where(lambda p: np.abs(p[:, 1] - top) < e)}
    return m.with_sets(node_sets=sets, facet_sets=facets), clamps


def assert_uniform_interference_pressure(m, delta=1e-6):
    """The two held blocks ``m`` pressed together by an interference ``delta`` through
    the condensed problem and the contact solver: uniform pressure ``E_u delta / (2 H)``
    (``H``: :data:`BLOCK_H`) at every contact point, no shear. Returns ``(pairing,
    reduced model, result)``."""
    dim = m.dim
    pr = make_pairing(m)
    A = [assemble_body(b) for b in m.bodies]
    rm = reduce_two_bodies(A[0], A[1], pr)
    prob = ContactProblem(rm.K, 0.3, gap0=np.full(pr.n_pairs, -delta), dim=dim)
    res = contact_solve(prob, rm.welded_contact_force([1.0]))
    assert res.success
    E_u = BLOCK_STEEL.E / (1 - BLOCK_STEEL.nu ** 2) if dim == 2 else BLOCK_STEEL.E
    traction = res.lam / pr.area[:, None]
    np.testing.assert_allclose(traction[:, -1], E_u * delta / (2 * BLOCK_H), rtol=1e-8)
    assert np.abs(traction[:, :-1]).max() < 1e-8 * E_u * delta / BLOCK_H
    return pr, rm, res


def annulus(r0, r1, nr, nt):
    """Full ring ``r0 <= r <= r1`` of nr x nt quads (the seam nodes merged)."""
    m = structured_mesh(np.linspace(r0, r1, nr + 1), np.linspace(0, 2 * np.pi, nt + 1))
    r, t = m.points[:, 0], m.points[:, 1]
    seam = np.isclose(t, 2 * np.pi)
    target = np.arange(len(r))
    target[seam] = np.flatnonzero(seam) - (nr + 1) * nt          # node (i, nt) -> (i, 0)
    number = np.cumsum(~seam) - 1
    mesh = Mesh(np.column_stack([r * np.cos(t), r * np.sin(t)])[~seam],
                number[target[m.cells]], "quad")
    on = lambda R: (lambda p: np.abs(np.hypot(p[:, 0], p[:, 1]) - R) < 1e-9 * r1)
    return mesh.with_sets(node_sets={"rim": np.flatnonzero(on(r1)(mesh.points))},
                          facet_sets={"in": mesh.boundary_facets_where(on(r0)),
                                      "out": mesh.boundary_facets_where(on(r1))})


def ring_interface_pressure(refine, n_outer, ring=None):
    """Inner ring (a..b, 48 refine elements around) welded by the mortar constraint to
    an outer ring (b..c, ``n_outer`` refine around, outer rim clamped), pressure p inside.
    Returns the pairing, the radial interface traction at the slave nodes and the Lame
    value (plane strain).
    ``ring(r0, r1, nr, nt)``: the ring's mesh (default :func:`annulus`)."""
    ring = ring or annulus
    a, b, c, p = 0.02, 0.03, 0.045, 1e7
    inner = Body("inner", ring(a, b, 6 * refine, 48 * refine), BLOCK_STEEL,
                 pressures=(Pressure("in", p),))
    outer = Body("outer", ring(b, c, 6 * refine, n_outer * refine), BLOCK_STEEL,
                 clamps=(Clamp("rim"),))
    m = Model((inner, outer), Interface("inner", "out", "outer", "in", coupling="auto"))
    pr = make_pairing(m)
    f = welded_body_forces(m, pr)[pr.slave - 1][pr.contact_nodes]
    radial = np.einsum("ij,ij->i", f, pr.x / np.linalg.norm(pr.x, axis=1)[:, None])
    # Lame, plane strain, u = A r + B / r with sigma_rr(a) = -p and u(c) = 0
    lam, mu = BLOCK_STEEL.lame
    A_ = -p / (2 * (lam + mu) + 2 * mu * c ** 2 / a ** 2)
    exact = -(2 * (lam + mu) * A_ + 2 * mu * A_ * c ** 2 / b ** 2)
    return pr, np.abs(radial) / pr.area, exact


def welded_body_forces(model, pairing):
    """Every contact point of ``pairing`` tied (the mortar constraint where it is one)
    and the preload solved: per body, the force the other body exerts on each of its
    nodes, ``K u - f_preload``, as an ``(n_nodes, dim)`` array."""
    A = [assemble_body(b) for b in model.bodies]
    T = tie_transform(model, A, pairing, np.ones(pairing.n_pairs, bool))
    K = (T.T @ stacked([a.K for a in A]) @ T).tocsc()
    F = np.concatenate([a.loads.get("preload", np.zeros(a.n_dofs)) for a in A])
    x = T @ spla.spsolve(K, T.T @ F)
    off = model.dof_offsets()
    return [(a.K @ x[off[k]:off[k + 1]] - a.loads.get("preload", np.zeros(a.n_dofs)))
            .reshape(-1, model.dim) for k, a in enumerate(A)]


def shifted_top(model, shift):
    """``model`` with the nodes of its second body moved along x by ``shift(points)``."""
    top = model.bodies[1]
    pts = top.mesh.points.copy()
    pts[:, 0] += shift(pts)
    mesh = Mesh(pts, top.mesh.cells, top.mesh.cell_type, top.mesh.node_sets,
                top.mesh.facet_sets)
    return dataclasses.replace(model, bodies=(model.bodies[0],
                                              dataclasses.replace(top, mesh=mesh)))


def jitter_contact_zone(p):
    """For :func:`shifted_top` on sandwich-2d: moves the top beam's nodes in the contact
    zone by up to 0.2 mm along x (a quarter of an element), keeping both ends of the zone
    and the node count."""
    L, lc = 0.2032, 0.0508
    s = (p[:, 0] - (L - lc)) / lc
    return np.where((s > 0) & (s < 1), 2e-4 * np.sin(np.pi * s) * np.sin(7 * np.pi * s), 0)


def assert_forced_mortar_is_node_to_node(model):
    """``model`` (conforming interface) run node to node and with the mortar coupling
    forced: the projection is the identity to round-off and f0, q and zeta agree to
    1e-8. Returns both results ``(node, mortar)`` and their pairings."""
    import qsma
    from qsma.model import make_pairing
    mm = dataclasses.replace(model, interface=dataclasses.replace(model.interface,
                                                                  coupling="mortar"))
    pn, pm = make_pairing(model), make_pairing(mm)
    assert pn.coupling == "node" and pm.coupling == "mortar"
    assert np.abs(pm.projection.toarray() - np.eye(pn.n_pairs)).max() < 1e-12
    a, b = qsma.run(model), qsma.run(mm)
    assert a.success and b.success
    assert b.f0_hz == pytest.approx(a.f0_hz, rel=1e-8)
    np.testing.assert_allclose(b.q, a.q, rtol=1e-8, atol=1e-8 * np.abs(a.q).max())
    np.testing.assert_allclose(b.zeta, a.zeta, rtol=1e-8, atol=1e-10)
    return a, b, pm


def split_body(body, axis, cut, names):
    """``body`` cut by the plane ``x[axis] = cut`` (a grid plane of its mesh) into two
    bodies named ``names`` (below, above the plane) with the same material, clamps and
    loads where their sets fall, each with the facet set ``"cut"`` on the plane:
    coincident nodes, for a tied interface between them. Node sets keep the nodes each
    part holds; facet sets the facets whose nodes all lie in the part."""
    from qsma.model import Body
    mesh = body.mesh
    centre = mesh.points[mesh.cells].mean(axis=1)[:, axis]
    eps = 1e-9 * float(np.ptp(mesh.points, axis=0).max())
    parts = []
    for keep in (centre < cut, centre > cut):
        cells = mesh.cells[keep]
        used, inverse = np.unique(cells, return_inverse=True)
        new = np.full(mesh.n_nodes, -1)
        new[used] = np.arange(len(used))
        node_sets = {k: new[v][new[v] >= 0] for k, v in mesh.node_sets.items()
                     if np.any(new[v] >= 0)}
        facet_sets = {}
        for k, f in mesh.facet_sets.items():
            f = f[np.all(new[f] >= 0, axis=1)]
            if len(f):
                facet_sets[k] = new[f]
        part = Mesh(mesh.points[used], inverse.reshape(cells.shape), mesh.cell_type,
                    node_sets, facet_sets, element=mesh.element)
        on = part.boundary_facets_where(lambda p: np.abs(p[:, axis] - cut) < eps)
        parts.append(part.with_sets(facet_sets={"cut": on}))
    out = []
    for name, part in zip(names, parts):
        sets = set(part.node_sets) | set(part.facet_sets)
        out.append(dataclasses.replace(
            body, name=name, mesh=part,
            clamps=tuple(c for c in body.clamps if c.set in sets),
            pressures=tuple(p for p in body.pressures if p.set in sets),
            forces=tuple(f for f in body.forces if f.set in sets)))
    return out


# ------------------------------------------------ decks as pre-processors write them
def tetra10_of(mesh):
    """:func:`tetrahedra_of` ``mesh`` with a node at the middle of every edge: 10-node
    tetrahedra (meshio = Abaqus C3D10 order: corners, then edges 1-2, 2-3, 3-1, 1-4, 2-4,
    3-4); no sets."""
    tets = tetrahedra_of(mesh).cells
    edges = tets[:, [0, 1, 1, 2, 2, 0, 0, 3, 1, 3, 2, 3]].reshape(-1, 2)
    unique, which = np.unique(np.sort(edges, axis=1), axis=0, return_inverse=True)
    mid = 0.5 * (mesh.points[unique[:, 0]] + mesh.points[unique[:, 1]])
    cells = np.hstack([tets, mesh.n_nodes + which.reshape(-1, 6)])
    return Mesh(np.vstack([mesh.points, mid]), cells, "tetra10")


def abaqus_face_elements(mesh, facets) -> dict:
    """``{k: element numbers (1-based)}`` of the cells whose Abaqus face ``S<k>`` is one
    of ``facets`` (node rows on the boundary): the rows of an element-face surface."""
    from qsma.mesh.celltypes import abaqus_faces
    from qsma.mesh.mesh import facet_index
    index = facet_index(mesh)
    wanted = index.find(facets)
    assert (wanted >= 0).all()
    out = {}
    for k, face in enumerate(abaqus_faces(mesh.cell_type), start=1):
        hit = np.flatnonzero(np.isin(index.find(mesh.cells[:, list(face)]), wanted))
        if hit.size:
            out[k] = hit + 1
    assert sum(len(v) for v in out.values()) == len(facets)
    return out


def cae_number(x) -> str:
    """A number as Abaqus/CAE writes it (``0.``, ``0.035``, ``7e+10``)."""
    s = f"{float(x):.12g}"
    return s if any(c in s for c in ".en") else s + "."


def cae_rounded(points):
    """``points`` as they read back from :func:`cae_number` (the deck's coordinates)."""
    return np.vectorize(lambda v: float(cae_number(v)))(points)


def id_rows(ids, per_line=16) -> str:
    """Ids as Abaqus writes set data lines: 16 a line, comma separated."""
    ids = [str(int(i)) for i in ids]
    return "".join(" " + ", ".join(ids[k:k + per_line]) + "\n"
                   for k in range(0, len(ids), per_line))


#: The lap joint of the pre-processor decks (SI): plates L x t x b overlapping by c, a
#: washer a x a in the middle of the overlap pressed by p (a bolt force of 8 kN), a
#: clamp block of 20 mm x t x b in the three-part joint; 5 mm elements.
PRE_LAP = dict(L=0.1, t=0.005, b=0.02, c=0.03, a=0.01, p=8e7, mu=0.2, nx=20, ny=2, nz=4)
ALUMINIUM, CAE_STEEL = Material(70e9, 0.33, 2700.0), Material(210e9, 0.3, 7850.0)
#: The three-part joint: the clamp block's top pushed down by 2 micrometres (a
#: ``*Boundary`` with a value), the bolt a force of 500 N on each of the 16 nodes of
#: the lower plate's washer (8 kN)
PRE_BLOCK_PUSH, PRE_BOLT_NODE_FORCE = -2e-6, 500.0


def _grid_mesh(lengths, counts, element):
    """A box ``[0, lengths]`` of ``counts`` cells of Abaqus type ``element`` (C3D8,
    C3D8I, C3D20R, C3D10, ...)."""
    axes = [np.linspace(0.0, a, n + 1) for a, n in zip(lengths, counts)]
    kind = {"C3D20": "hexahedron20"}.get(element.rstrip("RI"), None)
    mesh = structured_mesh(*axes, cell_type=kind)
    if element.startswith("C3D10"):
        mesh = tetra10_of(mesh)
    elif element.startswith("C3D4"):
        mesh = tetrahedra_of(mesh)
    mesh = Mesh(cae_rounded(mesh.points), mesh.cells, mesh.cell_type)
    return mesh


def _plate_part(name, lower, element, washer=True):
    """A plate in its own coordinates with its sets: ``clamp`` (nodes of its far end),
    ``interface`` (faces in the overlap), ``washer`` (the washer's faces on its outer
    side; ``under_block`` instead where a clamp block presses)."""
    s = PRE_LAP
    L, t, b, c, a = s["L"], s["t"], s["b"], s["c"], s["a"]
    m = _grid_mesh((L, t, b), (s["nx"], s["ny"], s["nz"]), element)
    e = 1e-9
    x, y, z = (lambda p, k=k: p[:, k] for k in range(3))
    xb = L - c / 2 if lower else c / 2
    in_overlap = (lambda p: x(p) >= L - c - e) if lower else (lambda p: x(p) <= c + e)
    y_if, y_out = (t, 0.0) if lower else (0.0, t)
    half = (a if washer else 2 * a) / 2
    facets = {
        "interface": m.boundary_facets_where(lambda p: (abs(y(p) - y_if) < e) & in_overlap(p)),
        "washer" if washer else "under_block": m.boundary_facets_where(
            lambda p: (abs(y(p) - y_out) < e) & (abs(x(p) - xb) <= half + e)
            & ((abs(z(p) - b / 2) <= a / 2 + e) if washer else True))}
    clamp = np.flatnonzero(abs(m.points[:, 0] - (0.0 if lower else L)) < e)
    return m.with_sets(node_sets={"clamp": clamp}, facet_sets=facets)


def _block_part(element):
    """The clamp block (20 mm x t x b) with ``bottom`` faces and ``top`` nodes."""
    s = PRE_LAP
    m = _grid_mesh((2 * s["a"], s["t"], s["b"]), (4, s["ny"], s["nz"]), element)
    y = m.points[:, 1]
    return m.with_sets(node_sets={"top": np.flatnonzero(abs(y - s["t"]) < 1e-9)},
                       facet_sets={"bottom": m.boundary_facets_where(
                           lambda p: abs(p[:, 1]) < 1e-9)})


def _generate_or_rows(ids) -> tuple:
    """(", generate" or "", data lines) of a set as CAE writes it: first, last, step
    where the ids are evenly spaced."""
    ids = np.asarray(ids)
    steps = np.unique(np.diff(ids))
    if len(ids) > 2 and len(steps) == 1:
        return ", generate", f" {ids[0]}, {ids[-1]}, {steps[0]}\n"
    return "", id_rows(ids)


def _cae_part(name, mesh, element, section_set, material):
    lines = [f"*Part, name={name}", "*Node"]
    lines += [f"{k:7d}, " + ", ".join(f"{cae_number(v):>13}" for v in p)
              for k, p in enumerate(mesh.points, start=1)]
    lines.append(f"*Element, type={element}")
    lines += [f"{k}, " + ", ".join(str(int(n) + 1) for n in row)
              for k, row in enumerate(mesh.cells, start=1)]
    internal = ", internal" if section_set.startswith("_") else ""
    lines += [f"*Nset, nset={section_set}{internal}, generate",
              f"  1, {mesh.n_nodes}, 1",
              f"*Elset, elset={section_set}{internal}, generate",
              f"  1, {len(mesh.cells)}, 1",
              f"** Section: Section-{name}",
              f"*Solid Section, elset={section_set}, material={material}", ",",
              "*End Part", "**  "]
    return "\n".join(lines) + "\n"


def _cae_surface(name, instance, mesh, facets) -> str:
    text = ""
    rows = []
    for k, elements in abaqus_face_elements(mesh, facets).items():
        gen, data = _generate_or_rows(elements)
        text += f"*Elset, elset=_{name}_S{k}, internal, instance={instance}{gen}\n{data}"
        rows.append(f"_{name}_S{k}, S{k}")
    return text + f"*Surface, type=ELEMENT, name={name}\n" + "\n".join(rows) + "\n"


def _cae_nset(name, instance, ids) -> str:
    gen, data = _generate_or_rows(np.asarray(ids) + 1)
    return f"*Nset, nset={name}, internal, instance={instance}{gen}\n{data}"


def cae_lap_deck(path, *, three_parts=False, element="C3D8I"):
    """A bolted lap joint as Abaqus/CAE writes its input file: an aluminium plate
    (``Lower``, in place) and a steel plate (``Upper``, translated) as parts and
    instances; the washer pressure by ``*Dsload`` on both outer faces, or (three parts)
    a steel clamp block (translated and rotated by 90 degrees about its vertical axis)
    pressed by a ``*Cload`` on its top nodes onto the upper plate; a ``*Contact Pair``
    (HARD, ``*Friction`` 0.2) between each two touching parts; supports ENCASTRE and
    PINNED (rows ``1, 1`` ... in the three-part deck) on internal node sets; ``Step-1``
    static with ``nlgeom=YES``, ``Step-2`` a ``perturbation`` ``*Frequency``.

    Returns the same model built through the Python API (bodies ``Lower-1``,
    ``Upper-1``[, ``Block-1``] in global coordinates, no probe)."""
    s = PRE_LAP
    L, t, c = s["L"], s["t"], s["c"]
    lower = _plate_part("Lower", True, element)
    upper = _plate_part("Upper", False, element, washer=not three_parts)
    shift_upper = np.array([L - c, t, 0.0])
    parts = _cae_part("Lower", lower, element, "_PickedSet2", "Aluminium") \
        + _cae_part("Upper", upper, element, "Set-1", "Steel")
    instances = ("*Instance, name=Lower-1, part=Lower\n*End Instance\n**  \n"
                 "*Instance, name=Upper-1, part=Upper\n"
                 + ", ".join(f"{cae_number(v):>13}" for v in shift_upper)
                 + "\n*End Instance\n**  \n")
    sets = _cae_nset("_PickedSet5", "Lower-1", lower.node_sets["clamp"]) \
        + _cae_nset("_PickedSet6", "Upper-1", upper.node_sets["clamp"]) \
        + _cae_surface("Surf-1", "Lower-1", lower, lower.facet_sets["interface"]) \
        + _cae_surface("Surf-2", "Upper-1", upper, upper.facet_sets["interface"]) \
        + _cae_surface("Surf-3", "Lower-1", lower, lower.facet_sets["washer"])
    block = None
    if three_parts:
        block = _block_part(element)
        shift_block = np.array([L - c + s["a"] / 2, 2 * t, 0.0])
        centre = shift_block + [s["a"], 0.0, s["b"] / 2]
        parts += _cae_part("Block", block, element, "Set-1", "Steel")
        instances += ("*Instance, name=Block-1, part=Block\n"
                      + ", ".join(f"{cae_number(v):>13}" for v in shift_block) + "\n"
                      + ", ".join(cae_number(v) for v in centre) + ", "
                      + ", ".join(cae_number(v) for v in centre + [0.0, 1.0, 0.0])
                      + ", 90.\n*End Instance\n**  \n")
        washer_nodes = np.unique(lower.facet_sets["washer"])
        sets += _cae_surface("Surf-4", "Upper-1", upper, upper.facet_sets["under_block"]) \
            + _cae_surface("Surf-5", "Block-1", block, block.facet_sets["bottom"]) \
            + _cae_nset("_PickedSet9", "Block-1", block.node_sets["top"]) \
            + _cae_nset("_PickedSet10", "Lower-1", washer_nodes)
        pin = ("_PickedSet6, 1, 1\n_PickedSet6, 2, 2\n_PickedSet6, 3, 3\n"
               "** Name: BC-3 Type: Displacement/Rotation\n*Boundary\n_PickedSet9, 1, 1\n"
               f"_PickedSet9, 2, 2, {cae_number(PRE_BLOCK_PUSH)}\n_PickedSet9, 3, 3\n")
        pairs = ("** Interaction: Int-1\n*Contact Pair, interaction=IntProp-1, "
                 "type=SURFACE TO SURFACE\nSurf-2, Surf-1\n** Interaction: Int-2\n"
                 "*Contact Pair, interaction=IntProp-1, small sliding, "
                 "type=SURFACE TO SURFACE, adjust=0.0\nSurf-5, Surf-4\n")
        loads = ("** Name: Load-1   Type: Concentrated force\n*Cload\n_PickedSet10, 2, "
                 f"{cae_number(PRE_BOLT_NODE_FORCE)}\n")
    else:
        sets += _cae_surface("Surf-4", "Upper-1", upper, upper.facet_sets["washer"])
        pin = "_PickedSet6, PINNED\n"
        pairs = ("** Interaction: Int-1\n*Contact Pair, interaction=IntProp-1, "
                 "type=SURFACE TO SURFACE\nSurf-2, Surf-1\n")
        loads = ("** Name: Load-1   Type: Pressure\n*Dsload\nSurf-3, P, "
                 f"{cae_number(s['p'])}\nSurf-4, P, {cae_number(s['p'])}\n")
    text = f"""*Heading
** Job name: Lap-Joint Model name: Lap-Joint
** Generated by: Abaqus/CAE 2022
*Preprint, echo=NO, model=NO, history=NO, contact=NO
**
** PARTS
**
{parts}**
** ASSEMBLY
**
*Assembly, name=Assembly
**  
{instances}{sets}*End Assembly
** 
** MATERIALS
** 
*Material, name=Aluminium
*Density
 2700.,
*Elastic
 7e+10, 0.33
*Material, name=Steel
*Density
 7850.,
*Elastic
 2.1e+11, 0.3
** 
** INTERACTION PROPERTIES
** 
*Surface Interaction, name=IntProp-1
1.,
*Friction
{cae_number(s["mu"])},
*Surface Behavior, pressure-overclosure=HARD
** 
** BOUNDARY CONDITIONS
** 
** Name: BC-1 Type: Symmetry/Antisymmetry/Encastre
*Boundary
_PickedSet5, ENCASTRE
** Name: BC-2 Type: Displacement/Rotation
*Boundary
{pin}** 
** INTERACTIONS
** 
{pairs}** ----------------------------------------------------------------
** 
** STEP: Step-1
** 
*Step, name=Step-1, nlgeom=YES
*Static
1., 1., 1e-05, 1.
** 
** LOADS
** 
{loads}** 
** OUTPUT REQUESTS
** 
*Restart, write, frequency=0
** 
** FIELD OUTPUT: F-Output-1
** 
*Output, field
*Node Output
CF, RF, U
*Element Output, directions=YES
LE, PE, PEEQ, PEMAG, S
*Contact Output
CDISP, CSTRESS
** 
** HISTORY OUTPUT: H-Output-1
** 
*Output, history, variable=PRESELECT
*End Step
** ----------------------------------------------------------------
** 
** STEP: Step-2
** 
*Step, name=Step-2, nlgeom=NO, perturbation
*Frequency, eigensolver=Lanczos, sim=NO, acoustic coupling=on, normalization=displacement
10, , , , , 
** 
** OUTPUT REQUESTS
** 
*Restart, write, frequency=0
** 
** FIELD OUTPUT: F-Output-2
** 
*Output, field, variable=PRESELECT
*End Step
"""
    path.write_text(text)
    return _lap_model(lower, upper, shift_upper, block,
                      shift_block if three_parts else None, element)


def _lap_model(lower, upper, shift_upper, block, shift_block, element):
    """The pre-processor lap joint through the Python API (global coordinates)."""
    s = PRE_LAP
    placed = lambda m, d: Mesh(m.points + d, m.cells, m.cell_type, m.node_sets,
                               m.facet_sets, element=element)
    p = s["p"]
    from qsma.model import NodalForce
    bolt = dict(pressures=(Pressure("washer", p),)) if block is None else \
        dict(forces=(NodalForce("washer_nodes", (0.0, PRE_BOLT_NODE_FORCE, 0.0)),))
    lower = lower.with_sets(node_sets={"washer_nodes": np.unique(lower.facet_sets["washer"])})
    bodies = [Body("Lower-1", placed(lower, 0.0), ALUMINIUM, clamps=(Clamp("clamp"),),
                   **bolt),
              Body("Upper-1", placed(upper, shift_upper), CAE_STEEL,
                   clamps=(Clamp("clamp"),),
                   pressures=() if block is not None else (Pressure("washer", p),))]
    itf = [Interface("Lower-1", "interface", "Upper-1", "interface", mu=s["mu"])]
    if block is not None:
        bodies.append(Body("Block-1", placed(block, shift_block), CAE_STEEL, clamps=(
            Clamp("top", (0, 2)), Clamp("top", (1,), (PRE_BLOCK_PUSH,)))))
        itf.append(Interface("Upper-1", "under_block", "Block-1", "bottom", mu=s["mu"]))
    if len(itf) == 1:
        return Model(tuple(bodies), itf[0], mu=s["mu"])
    return Model(tuple(bodies), interfaces=tuple(itf), mu=s["mu"])


#: The FreeCAD FEM lap joint in mm-N-s-tonne: the linear contact's slope (N/mm^3) and
#: the stick slope of its *FRICTION (N/mm^3)
FREECAD_LAW = {"normal": "linear", "normal_stiffness": 1e6, "tangential": "elastic",
               "tangential_stiffness": 1e5}


def _one_per_line(ids) -> str:
    """Set members as FreeCAD writes them: one a line, with a trailing comma."""
    return "".join(f"{int(i)},\n" for i in ids)


def freecad_lap_deck(folder, *, contact_type="SURFACE TO SURFACE", element="C3D10",
                     gap=0.0):
    """The two-plate lap joint (aluminium under steel, C3D10) as FreeCAD FEM writes a
    CalculiX deck (mm, N, tonne): upper-case keywords, the mesh, its sets and the
    contact surfaces in *INCLUDE files, ``*NODE, NSET=Nall``, ``*ELEMENT, TYPE=C3D10,
    ELSET=Eall``, an element set per material, ``*SURFACE`` rows ``eid,S<k>``, the
    washer pressure as ``*DLOAD`` rows ``eid,P<k>,80.0``, supports on node sets
    (``ConstraintFixed,1`` ... and ``ConstraintDisplacement,1,3``), a LINEAR
    ``*SURFACE BEHAVIOR`` with ``*FRICTION`` mu and stick slope, a ``*STATIC`` then a
    ``*FREQUENCY`` step; ``**`` comments and blank lines everywhere, Windows line ends.

    ``gap``: the upper plate lifted by that much (mm), as FreeCAD users leave a small
    gap between solids meshed in one go.

    Returns ``(deck path, the same model through the Python API)``; the bodies are
    named after their material's element set, as the deck reader names them."""
    s = PRE_LAP
    mm = 1e3
    lower = _plate_part("lower", True, element)
    upper = _plate_part("upper", False, element)
    meshes = []
    for m, shift in ((lower, np.zeros(3)),
                     (upper, np.array([s["L"] - s["c"], s["t"] + gap / mm, 0.0]))):
        meshes.append(Mesh(cae_rounded((m.points + shift) * mm), m.cells, m.cell_type,
                           m.node_sets, m.facet_sets, element=element))
    n0, e0 = meshes[0].n_nodes, len(meshes[0].cells)
    nodes = "".join(f"{k}, " + ", ".join(f"{v:.13g}" for v in p) + "\n" for k, p in
                    enumerate(np.vstack([m.points for m in meshes]), start=1))
    cells = np.vstack([meshes[0].cells, meshes[1].cells + n0]) + 1
    elements = "".join(f"{k}, " + ", ".join(map(str, row)) + "\n"
                       for k, row in enumerate(cells, start=1))
    mesh_file = ("** written by FreeCAD inp file writer for CalculiX,Abaqus meshes\n"
                 "** highest dimension mesh elements only.\n\n** Nodes\n*NODE, NSET=Nall\n"
                 f"{nodes}\n\n** Volume elements\n*ELEMENT, TYPE={element}, ELSET=Evolumes\n"
                 f"{elements}\n** Define element set Eall\n*ELSET, ELSET=Eall\nEvolumes\n\n"
                 "***********************************************************\n"
                 "** Element sets for materials and FEM element type (solid, shell, beam, "
                 "fluid)\n** written by write_element_sets_material_and_femelement_type "
                 "function\n*ELSET,ELSET=SolidMaterialSolid\n"
                 + _one_per_line(np.arange(1, e0 + 1))
                 + "*ELSET,ELSET=SolidMaterial001Solid\n"
                 + _one_per_line(np.arange(e0 + 1, len(cells) + 1)))
    node_sets = ("***********************************************************\n"
                 "** Node sets for fixed constraint\n** written by "
                 "write_node_sets_constraints_fixed function\n** ConstraintFixed\n"
                 "*NSET,NSET=ConstraintFixed\n"
                 + _one_per_line(meshes[0].node_sets["clamp"] + 1)
                 + "\n** Node sets for prescribed displacement constraint\n"
                 "** ConstraintDisplacement\n*NSET,NSET=ConstraintDisplacement\n"
                 + _one_per_line(meshes[1].node_sets["clamp"] + 1 + n0))

    def face_rows(m, name, off, fmt):
        return "".join(fmt.format(e + off, k) for k, els in
                       abaqus_face_elements(m, m.facet_sets[name]).items() for e in els)
    surfaces = ("***********************************************************\n"
                "** Surfaces for contact constraint\n** ConstraintContact\n"
                "*SURFACE, NAME=DEPConstraintContact, TYPE=ELEMENT\n"
                + face_rows(meshes[1], "interface", e0, "{},S{}\n")
                + "*SURFACE, NAME=INDConstraintContact, TYPE=ELEMENT\n"
                + face_rows(meshes[0], "interface", 0, "{},S{}\n"))
    p = s["p"] / mm ** 2
    dload = (face_rows(meshes[0], "washer", 0, "{},P{}," + f"{p}\n")
             + face_rows(meshes[1], "washer", e0, "{},P{}," + f"{p}\n"))
    mu, kn, kt = s["mu"], FREECAD_LAW["normal_stiffness"], FREECAD_LAW["tangential_stiffness"]
    deck = f"""**
** Structure: lap joint.
** Generated by FreeCAD
**

***********************************************************
** Mesh, sets and surfaces (written to include files)
*INCLUDE,INPUT=lap_Node_Elem_sets.inp
*INCLUDE,INPUT=lap_Node_sets.inp
*INCLUDE,INPUT=lap_Surface_sets.inp

***********************************************************
** Materials
** Young's modulus unit is MPa = N/mm2
** Density's unit is t/mm^3
** FreeCAD material name: Aluminium-Generic
** SolidMaterial
*MATERIAL, NAME=SolidMaterial
*ELASTIC
70000, 0.330
*DENSITY
2.700e-09
** FreeCAD material name: Steel-Generic
** SolidMaterial001
*MATERIAL, NAME=SolidMaterial001
*ELASTIC
210000, 0.300
*DENSITY
7.850e-09

***********************************************************
** Sections
*SOLID SECTION, ELSET=SolidMaterialSolid, MATERIAL=SolidMaterial
*SOLID SECTION, ELSET=SolidMaterial001Solid, MATERIAL=SolidMaterial001

***********************************************************
** Contact Constraints
** ConstraintContact
*CONTACT PAIR, INTERACTION=INTConstraintContact,TYPE={contact_type}
DEPConstraintContact,INDConstraintContact
*SURFACE INTERACTION, NAME=INTConstraintContact
*SURFACE BEHAVIOR,PRESSURE-OVERCLOSURE=LINEAR
{kn:.1f} 
*FRICTION
{mu}, {kt:.1f}

***********************************************************
** At least one step is needed to run an CalculiX analysis of FreeCAD
*STEP, INC=2000
*STATIC


***********************************************************
** Fixed Constraints
** ConstraintFixed
*BOUNDARY
ConstraintFixed,1
ConstraintFixed,2
ConstraintFixed,3

***********************************************************
** Displacement constraint applied
** ConstraintDisplacement
*BOUNDARY
ConstraintDisplacement,1,3


***********************************************************
** constraints pressure element face loads
** ConstraintPressure
*DLOAD
** ConstraintPressure: face load
{dload}
***********************************************************
** Outputs --> frd file
*NODE FILE
U
*EL FILE
S, E
** outputs --> dat file
** reaction forces for Constraint fixed
*NODE PRINT, NSET=ConstraintFixed, TOTALS=ONLY
RF


***********************************************************
*END STEP 

***********************************************************
** Frequency analysis
*STEP
*FREQUENCY
10, 0.0, 1000000.0
*NODE FILE
U
*END STEP 

***********************************************************
** CalculiX Input file
**  About units:
**  Length: mm, Mass: t, Force: N, Pressure: N/mm^2, Density: t/mm^3
**
"""
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in (("lap.inp", deck), ("lap_Node_Elem_sets.inp", mesh_file),
                       ("lap_Node_sets.inp", node_sets),
                       ("lap_Surface_sets.inp", surfaces)):
        with open(folder / name, "w", newline="\r\n") as f:
            f.write(text)
    return folder / "lap.inp", _freecad_model(meshes, p)


def _freecad_model(meshes, p):
    """The FreeCAD lap joint through the Python API (mm-N-s-tonne)."""
    from qsma.contact.laws import law_from_table
    al, st = Material(70000.0, 0.33, 2.7e-9), Material(210000.0, 0.3, 7.85e-9)
    lower, upper = "SolidMaterialSolid", "SolidMaterial001Solid"
    bodies = tuple(Body(name, m, mat, clamps=(Clamp("clamp"),),
                        pressures=(Pressure("washer", p),))
                   for name, m, mat in ((lower, meshes[0], al), (upper, meshes[1], st)))
    itf = Interface(lower, "interface", upper, "interface", mu=PRE_LAP["mu"],
                    law=law_from_table(FREECAD_LAW))
    return Model(bodies, itf, mu=PRE_LAP["mu"], units="mm-N-s-tonne")
