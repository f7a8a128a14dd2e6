"""Meshed bolts cut by a pretension section (:class:`qsma.model.SectionBolt`,
:mod:`qsma.fe.sections`, docs/theory.md section 11): closed forms on a bar, the
refusals, and the bolted joint with a meshed bolt (the preload's forces, locking,
the tied frequency of the uncut mesh)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse.linalg as spla

import qsma
from helpers import load_benchmark, needs_ccx, tetrahedra_of

from qsma.analysis import Levels, RunOptions
from qsma.analysis.clock import StageClock
from qsma.analysis.prepared import prepare
from qsma.analysis.result import load_factors
from qsma.contact import OPEN
from qsma.analysis.config import parse_config
from qsma.deck import export_calculix, read_deck
from qsma.deck.calculix_output import displacements, run_calculix
from qsma.errors import InputError
from qsma.examples.meshed_bolt import MESHED_BOLT, meshed_bolt_joint
from qsma.fe import assemble_body
from qsma.fe.sections import cells_stiffness, cut_stiffness, section_terms
from qsma.mesh import read_mesh
from qsma.mesh.generate import cell_faces, structured_mesh
from qsma.modal import linear_modes
from qsma.model import Body, Interface, Material, SectionBolt
from qsma.model.pairing import make_pairing

E, L, A_SIDE, N0 = 2e11, 1.0, 0.1, 1e5


def _bar(dim=3, nx=10, side="right", section=None):
    """A bar along x (square section A_SIDE wide, nu = 0) cut at x = L / 2, the faces
    owned by the cells on ``side``."""
    axes = [np.linspace(0, L, nx + 1)] + [np.linspace(0, A_SIDE, 3)] * (dim - 1)
    m = structured_mesh(*axes)
    centres = m.points[m.cells].mean(axis=1)
    owners = np.flatnonzero(centres[:, 0] > L / 2 if side == "right"
                            else centres[:, 0] < L / 2)
    at = lambda p: np.isclose(p[:, 0], L / 2) if section is None else section(p)
    m = m.with_sets(facet_sets={"cut": cell_faces(m, owners, at)})
    return Body("bar", m, Material(E, 0.0, 7800.0))


def _clamped_solve(body, K, f):
    """``K u = f`` with both ends of the bar clamped; ``(u, K u - f)``."""
    dim = body.dim
    ends = np.isclose(body.mesh.points[:, 0], 0) | np.isclose(body.mesh.points[:, 0], L)
    free = np.flatnonzero(~np.repeat(ends, dim))
    u = np.zeros(K.shape[0])
    u[free] = spla.spsolve(K[free][:, free].tocsc(), f[free])
    return u, K @ u - f


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("side", ["right", "left"])
def test_bar_clamped_at_both_ends_closed_form(dim, side):
    """A bar clamped at both ends, cut in the middle, pretension N0 (nu = 0: uniaxial):
    the ends' reactions are N0 pulling outwards, every cell off the cut carries the
    stress N0 / A (its strain N0 / (E A)), gamma is E A / h of the owner layer (h the
    cell length), the opening is a null vector of the cut stiffness, and locking
    (adding gamma c c^T) gives back the uncut K, so the locked bar's axial frequency is
    the uncut bar's."""
    body = _bar(dim, side=side)
    t = section_terms(body, SectionBolt("b", "bar", "cut", N0))
    area = A_SIDE ** (dim - 1)
    h = L / 10
    assert t.gamma == pytest.approx(E * area / h, rel=1e-12)
    assert t.area == pytest.approx(area, rel=1e-12)
    assert t.normal[0] == (-1.0 if side == "right" else 1.0)       # out of the owners
    K = assemble_body(body).K
    K_cut = cut_stiffness(K, t)
    assert np.abs(K_cut @ t.opening).max() < 1e-12 * abs(K).max()
    u, r = _clamped_solve(body, K_cut, -N0 * t.c)
    x = body.mesh.points[:, 0]
    rx = r[0::dim]
    assert rx[np.isclose(x, 0)].sum() == pytest.approx(-N0, rel=1e-10)
    assert rx[np.isclose(x, L)].sum() == pytest.approx(N0, rel=1e-10)
    assert abs(r[1::dim].sum()) < 1e-9 * N0
    # strain of every cell from its corner displacements, away from the cut's owners
    cells = body.mesh.cells
    ux = u[0::dim][cells]
    xs = x[cells]
    strain = (ux.max(axis=1) - ux.min(axis=1)) / (xs.max(axis=1) - xs.min(axis=1))
    off = np.setdiff1d(np.arange(len(cells)), t.owners)
    assert np.allclose(strain[off], N0 / (E * area), rtol=1e-9)
    K_locked = K_cut.toarray() + t.gamma * np.outer(t.c, t.c)
    assert np.abs(K_locked - K.toarray()).max() < 1e-9 * abs(K).max()
    M = assemble_body(body).M.toarray()
    ends = np.isclose(x, 0) | np.isclose(x, L)
    keep = np.flatnonzero(~np.repeat(ends, dim))
    w_locked = sla.eigh(K_locked[np.ix_(keep, keep)], M[np.ix_(keep, keep)],
                        eigvals_only=True, subset_by_index=[0, 5])
    w_uncut = sla.eigh(K.toarray()[np.ix_(keep, keep)], M[np.ix_(keep, keep)],
                       eigvals_only=True, subset_by_index=[0, 5])
    assert np.allclose(w_locked, w_uncut, rtol=1e-9)


def test_section_refusals():
    """A face on the boundary, a section that does not cut the bar in two (over half
    the cross-section; or through tetrahedra, some of which meet the cut at an edge on
    the owners' side and keep its nodes, as CalculiX leaves them), a normal pointing
    into the owners and an unknown set are refused by name."""
    body = _bar()
    with pytest.raises(InputError, match="no facet set"):
        section_terms(body, SectionBolt("b", "bar", "nope", N0))
    with pytest.raises(InputError, match="points into the cells"):
        section_terms(body, SectionBolt("b", "bar", "cut", N0, normal=(1.0, 0.0, 0.0)))
    half = _bar(section=lambda p: np.isclose(p[:, 0], L / 2) & (p[:, 1] < 0.5 * A_SIDE + 1e-9))
    with pytest.raises(InputError, match="does not cut the body in two"):
        section_terms(half, SectionBolt("b", "bar", "cut", N0))
    tets = tetrahedra_of(_bar().mesh)
    c = tets.points[tets.cells].mean(axis=1)
    faces = cell_faces(tets, np.flatnonzero(c[:, 0] > L / 2),
                       lambda p: np.isclose(p[:, 0], L / 2))
    leaky = Body("bar", tets.with_sets(facet_sets={"cut": faces}), Material(E, 0.0, 7800.0))
    with pytest.raises(InputError, match="touch it without a face on it"):
        section_terms(leaky, SectionBolt("b", "bar", "cut", N0))
    end = _bar(section=lambda p: np.isclose(p[:, 0], L))
    with pytest.raises(InputError, match="on the boundary"):
        section_terms(end, SectionBolt("b", "bar", "cut", N0))
    with pytest.raises(InputError, match="pretension must be > 0"):
        SectionBolt("b", "bar", "cut", -1.0)


def test_a_given_normal_at_an_angle_is_the_section_normal():
    """A NORMAL given at an angle to the faces (CalculiX's data line) is used as given:
    the uniform relative displacement of the cut is along it, and the force the far
    end's clamp carries (the force across the section) has the component N0 along it
    (the tangential part is what the tied components carry)."""
    n = np.array([-1.0, 0.2, 0.0]) / np.sqrt(1.04)
    body = _bar()
    t = section_terms(body, SectionBolt("b", "bar", "cut", N0, normal=tuple(n)))
    assert np.allclose(t.normal, n)
    _, r = _clamped_solve(body, cut_stiffness(assemble_body(body).K, t), -N0 * t.c)
    x = body.mesh.points[:, 0]
    right = np.isclose(x, L)
    force = np.array([r[c::3][right].sum() for c in range(3)])
    assert force @ n == pytest.approx(-N0, rel=1e-10)
    assert abs(force[1]) > 1e-3 * N0                  # not along the faces' normal


@pytest.fixture(scope="module")
def joint():
    m = meshed_bolt_joint(1)
    p = prepare(m, RunOptions())
    red, layer, pre = p.preloaded(RunOptions(), StageClock())
    return m, p, red, pre


def test_joint_preload_carries_the_pretension(joint):
    """The preload of the meshed bolt: the head's contact and the plates' contact each
    carry N0 (the top plate is held only by the joint), with no net shear, and the
    shank below the section (cells of side A only, from the recovered field) carries
    N0 too."""
    m, p, red, pre = joint
    N0_ = MESHED_BOLT["pretension"]
    z = p.pairing.x[:, 2]
    for level in (4.0, 8.0):
        assert pre.P[np.isclose(z, level)].sum() == pytest.approx(N0_, rel=1e-10)
    assert np.abs(pre.Q.sum(axis=0)).max() < 1e-10 * N0_
    u_base, _ = red.recover(pre.d, load_factors(red, 0.0))
    base = m.bodies[0]
    pts = base.mesh.points
    c = pts[base.mesh.cells].mean(axis=1)
    slab = np.flatnonzero((np.abs(c[:, 0] - 10) < 2) & (np.abs(c[:, 1] - 10) < 2)
                          & (c[:, 2] > 4) & (c[:, 2] < MESHED_BOLT["z_cut"]))
    K_slab = cells_stiffness(base, slab)
    f = K_slab @ u_base
    foot = np.flatnonzero(np.isclose(pts[:, 2], 4.0) & (np.abs(pts[:, 0] - 10) < 2 + 1e-9)
                          & (np.abs(pts[:, 1] - 10) < 2 + 1e-9))
    assert -f[3 * foot + 2].sum() == pytest.approx(N0_, rel=1e-10)


def test_joint_locking_keeps_the_preload_in_equilibrium(joint):
    """The locked model gives, at the preload's relative displacement, the preload's
    contact forces, and the bolt force N0 there; a change of d changes the bolt force
    by gamma times the change of the elongation."""
    m, p, red, pre = joint
    a = load_factors(red, 0.0)
    lam = red.K @ pre.d.ravel() + red.W @ a
    scale = np.abs(pre.lam).max()
    assert np.abs(lam - pre.lam.ravel()).max() < 1e-9 * scale
    assert red.bolt_forces(pre.d, a)[0] == pytest.approx(MESHED_BOLT["pretension"],
                                                          rel=1e-12)
    gamma = section_terms(m.bodies[0], m.bolts[0]).gamma
    rng = np.random.default_rng(0)
    d = pre.d.ravel() + 1e-6 * rng.standard_normal(pre.d.size)
    u0 = red.recover(pre.d, a)[0]
    u1 = red.recover(d, a)[0]
    c = section_terms(m.bodies[0], m.bolts[0]).c
    dN = red.bolt_forces(d, a)[0] - MESHED_BOLT["pretension"]
    assert dN == pytest.approx(gamma * c @ (u1 - u0), rel=1e-7)


def test_joint_tied_frequency_is_the_uncut_mesh(joint):
    """The run's tied mode (locked bolt, pairs closed by the preload tied) has the
    frequency of the uncut mesh with the same pairs tied (equal to round-off at
    refine 1: 81086.2547347 Hz in both)."""
    m, p, red, pre = joint
    res = qsma.run(m, RunOptions(levels=Levels.log("tip", 1e-7, 1e-6, 2)))
    plain = replace(m, bolts=())
    modes = linear_modes(plain, [assemble_body(b) for b in plain.bodies],
                         make_pairing(plain), pre.status != OPEN, 2)
    assert res.f0_hz == pytest.approx(modes.omega[0] / (2 * np.pi), rel=1e-9)


# --- the deck and CalculiX ------------------------------------------------------------
def test_the_deck_of_a_meshed_bolt_reads_back(tmp_path):
    """qsma's CalculiX deck of the joint writes the section as CalculiX's
    *PRE-TENSION SECTION, SURFACE= (faces of the owner cells, S-numbered, its normal)
    with the *CLOAD in the preload and the node held after; read back, the deck gives
    the same meshed bolt and the same preload (contact force 2 N0 over both zones)."""
    m = meshed_bolt_joint(1, mu=1.0)
    path = tmp_path / "joint.inp"
    export_calculix(m, path)
    text = path.read_text()
    assert "*PRE-TENSION SECTION, SURFACE=BASE_CUT, NODE=" in text
    deck = read_deck(path)
    assert not deck.refusals
    (table,) = deck.config["bolts"]
    assert table["pretension"] == MESHED_BOLT["pretension"]
    assert table["normal"] == [0.0, 0.0, -1.0]
    read = parse_config(deck.config, base=tmp_path).model
    (bolt,) = read.bolts
    assert isinstance(bolt, SectionBolt) and bolt.body == "base"
    mine = section_terms(m.bodies[0], m.bolts[0])
    theirs = section_terms(read.bodies[0], bolt)
    assert theirs.gamma == pytest.approx(mine.gamma, rel=1e-12)
    p = prepare(read, RunOptions())
    _, _, pre = p.preloaded(RunOptions(), StageClock())
    assert pre.P.sum() == pytest.approx(2 * MESHED_BOLT["pretension"], rel=1e-10)
    table["stiffness"] = 1e9                          # a meshed bolt's is the mesh's
    with pytest.raises(InputError, match="its stiffness is the mesh's"):
        parse_config(deck.config, base=tmp_path)


@pytest.fixture(scope="module")
def calculix(tmp_path_factory):
    """The joint (mu = 1) in CalculiX 2.20 and in qsma
    (benchmarks/bench_meshed_bolt_calculix.py: qsma's export, node-to-surface penalty
    contact of slope 1e4 E / h, the section as CalculiX's own, and the tied deck)."""
    bench = load_benchmark("bench_meshed_bolt_calculix")
    return bench.compare(1, 1.0, tmp_path_factory.mktemp("meshed-bolt"))


@needs_ccx
def test_meshed_bolt_preload_against_calculix(calculix):
    """After the preload both codes carry N0 across each contact zone (the top plate's
    nodal forces K u) and through the shank below the section (the side-A cells'
    forces, from each code's displacements); the nodal contact forces agree to 9.0e-4
    of the largest and the displacement fields to 3.5e-3 of the largest (measured:
    CalculiX's penalty and its incremental friction path; at mu = 0.3, where 32 pairs
    slip, to 1.2e-2 and 6.8e-2, docs/validation.md)."""
    row = calculix
    N0_ = MESHED_BOLT["pretension"]
    for (q, c), sign in ((row["zones"]["z4"], 1), (row["zones"]["z8"], -1)):
        assert q == pytest.approx(sign * N0_, rel=1e-10)
        assert c == pytest.approx(sign * N0_, rel=1e-6)       # CalculiX prints 7 digits
    assert row["shank"][0] == pytest.approx(N0_, rel=1e-10)
    assert row["shank"][1] == pytest.approx(N0_, rel=1e-6)
    assert row["df"] < 2e-3 and row["du"] < 1e-2


@needs_ccx
def test_meshed_bolt_tied_frequency_against_calculix(calculix):
    """The tied structure (pairs the preload closed tied, the section's node held):
    CalculiX's first frequency is qsma's f0 to its 7 printed digits (81086.25 Hz)."""
    f_qsma, f_ccx = calculix["f0"]
    assert f_ccx == pytest.approx(f_qsma, rel=1e-6)


def test_several_interfaces_are_refused_by_name():
    """With several interfaces (here the joint's two contact zones as two interfaces)
    a body whose pretension section opens freely in the preload is held only through
    them, which that path does not support yet: refused, naming the section."""
    m = meshed_bolt_joint(1)
    bodies = []
    for b in m.bodies:
        rows = b.mesh.facet_sets["contact"]
        z = b.mesh.points[rows].mean(axis=1)[:, 2]
        sets = {"plates": rows[np.isclose(z, 4.0)], "head": rows[np.isclose(z, 8.0)]}
        bodies.append(replace(b, mesh=b.mesh.with_sets(facet_sets=sets)))
    interfaces = tuple(Interface("base", s, "plate", s) for s in ("plates", "head"))
    split = replace(m, bodies=tuple(bodies), interface=None, interfaces=interfaces)
    with pytest.raises(InputError, match="cut by a pretension section"):
        prepare(split, RunOptions())


TWO_QUADS = """*NODE, NSET=NALL
1, 0., 0., 0.
2, 1., 0., 0.
3, 2., 0., 0.
4, 0., 1., 0.
5, 1., 1., 0.
6, 2., 1., 0.
7, 1., 0.5, 0.
*ELEMENT, TYPE=CPE4, ELSET=EALL
1, 1, 2, 5, 4
2, 2, 3, 6, 5
*BOUNDARY
1, 1, 2
3, 1, 2
4, 1, 2
6, 1, 2
*MATERIAL, NAME=EL
*ELASTIC
210000., .3
*SOLID SECTION, ELSET=EALL, MATERIAL=EL
1.
*SURFACE, NAME=SURF1
1, S2
*PRE-TENSION SECTION, SURFACE=SURF1, NODE=7
1., 0., 0.
*STEP
*STATIC
*CLOAD
7, 1, 10.
*NODE PRINT, NSET=NALL
U
*END STEP
"""


@needs_ccx
def test_section_of_two_quads_against_calculix(tmp_path):
    """CalculiX's test deck pret5 (two CPE4 between clamped ends, the section their
    common face owned by the left one), with a tension of 10 N per unit depth instead
    of its compression: qsma's cut of the face the mesh reader keeps gives CalculiX's
    displacements to its 7 printed digits, and the same opening of the section (the
    pretension node's displacement, -N0 / gamma + ell)."""
    path = tmp_path / "quads.inp"
    path.write_text(TWO_QUADS)
    (_, u_ccx), = displacements(run_calculix(path), 7)
    bare = tmp_path / "mesh.inp"                       # the mesh without node 7
    bare.write_text(TWO_QUADS.replace("7, 1., 0.5, 0.\n", ""))
    mesh = read_mesh(bare)
    body = Body("quads", mesh, Material(210000.0, 0.3, 7.85e-9))
    t = section_terms(body, SectionBolt("b", "quads", "SURF1", 10.0, normal=(1.0, 0.0)))
    K = cut_stiffness(assemble_body(body).K, t)
    clamped = np.repeat(np.isin(np.arange(6), [0, 2, 3, 5]), 2)
    free = np.flatnonzero(~clamped)
    u = np.zeros(12)
    u[free] = spla.spsolve(K[free][:, free].tocsc(), (-10.0 * t.c)[free])
    u = u.reshape(-1, 2)
    assert np.abs(u - u_ccx[:6, :2]).max() < 1e-6 * np.abs(u).max()
    opening = 10.0 / t.gamma - t.c @ u.ravel()         # delta = (N0 - v^T u) / gamma
    assert opening == pytest.approx(u_ccx[6, 0], rel=1e-6)
