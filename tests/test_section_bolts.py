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

from qsma.analysis import Levels, RunOptions
from qsma.analysis.clock import StageClock
from qsma.analysis.prepared import prepare
from qsma.analysis.result import load_factors
from qsma.contact import OPEN
from qsma.errors import InputError
from qsma.examples.meshed_bolt import MESHED_BOLT, meshed_bolt_joint
from qsma.fe import assemble_body
from qsma.fe.sections import cells_stiffness, cut_stiffness, section_terms
from qsma.mesh.generate import cell_faces, structured_mesh
from qsma.modal import linear_modes
from qsma.model import Body, Material, SectionBolt
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
    """A face on the boundary, a section that does not cut the bar in two, a normal
    pointing into the owners and an unknown set are refused by name."""
    body = _bar()
    with pytest.raises(InputError, match="no facet set"):
        section_terms(body, SectionBolt("b", "bar", "nope", N0))
    with pytest.raises(InputError, match="points into the cells"):
        section_terms(body, SectionBolt("b", "bar", "cut", N0, normal=(1.0, 0.0, 0.0)))
    half = _bar(section=lambda p: np.isclose(p[:, 0], L / 2) & (p[:, 1] < 0.5 * A_SIDE + 1e-9))
    with pytest.raises(InputError, match="does not cut the body in two"):
        section_terms(half, SectionBolt("b", "bar", "cut", N0))
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
