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
