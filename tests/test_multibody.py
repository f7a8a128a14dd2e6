"""Several bodies and interfaces: the combination against the two-body formulas and a
full constrained solve."""
import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from qsma.condense import reduce_two_bodies
from qsma.contact import ContactProblem, residual, solve as contact_solve
from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.model import Body, Clamp, Interface, Material, Model, Pressure, make_pairing
from qsma.model.generate import graded_axis, structured_mesh
from qsma.multibody import Coupling, reduce_bodies

STEEL = Material(200e9, 0.3, 7800.0)


@pytest.mark.parametrize("coupling", ["node", "mortar"])
def test_two_bodies_equal_the_two_body_formulas(coupling):
    """One coupling through reduce_bodies is the two-body model: K, W and the recovered
    fields to 1e-9 (measured: 3.5e-15, 1e-10, 1e-11 node-to-node; 5e-16, 2e-15, 4e-12
    mortar)."""
    m = sandwich_2d(1)
    m = dataclasses.replace(m, interface=dataclasses.replace(m.interface, coupling=coupling))
    A = [assemble_body(b) for b in m.bodies]
    p = make_pairing(m)
    two = reduce_two_bodies(A[0], A[1], p)
    multi = reduce_bodies(A, [Coupling(p, 0, 1)])
    scale = np.abs(two.K).max()
    assert np.abs(multi.K - two.K).max() < 1e-9 * scale
    assert np.abs(multi.W - two.W).max() < 1e-9 * np.abs(two.W).max()
    rng = np.random.default_rng(4)
    d = rng.normal(size=two.K.shape[0]) * 1e-7
    for u, v in zip(multi.recover(d, [1.0]), two.recover(d, [1.0])):
        assert np.abs(u - v).max() < 1e-9 * np.abs(v).max()


def _three_layers(fine=(64, 48, 64)):
    """Three clamped beams stacked (a bolted three-layer sandwich): the middle one meshed
    with ``fine[1]`` elements along the contact zone, the others with 64."""
    L, h, lc = 0.2032, 0.00635, 0.0508
    eps = 1e-9 * L
    bodies = []
    for k, (name, nf) in enumerate(zip(("bottom", "middle", "top"), fine)):
        xs = graded_axis((0.0, L - lc, 60), (L - lc, L, nf))
        m = structured_mesh(xs, np.linspace(k * h, (k + 1) * h, 5))
        zone = lambda y: (lambda p: (np.abs(p[:, 1] - y) < eps) & (p[:, 0] >= L - lc - eps))
        bolt = lambda y: (lambda p: (np.abs(p[:, 1] - y) < eps)
                          & (np.abs(p[:, 0] - (L - lc / 2)) <= 0.00635 / 2 + eps))
        m = m.with_sets(node_sets={"clamp": np.flatnonzero(m.points[:, 0] < eps)},
                        facet_sets={"lower": m.boundary_facets_where(zone(k * h)),
                                    "upper": m.boundary_facets_where(zone((k + 1) * h)),
                                    "bolt": m.boundary_facets_where(
                                        bolt(0.0 if k == 0 else 3 * h))})
        pressures = (Pressure("bolt", 17.554e6),) if k != 1 else ()
        bodies.append(Body(name, m, STEEL, clamps=(Clamp("clamp"),), pressures=pressures))
    return bodies


def _pairings(bodies):
    out = []
    for i, (lo, hi) in enumerate(((0, 1), (1, 2))):
        model = Model((bodies[lo], bodies[hi]),
                      Interface(bodies[lo].name, "upper", bodies[hi].name, "lower",
                                coupling="auto"))
        out.append(Coupling(make_pairing(model), lo, hi))
    return out


def test_three_bodies_two_nonmatching_interfaces_welded_equal_constrained_solve():
    """Plate - (differently meshed) middle plate - plate, both interfaces mortar: the
    welded answer (d = 0) equals the full sparse solve with the constraints G x = 0
    imposed by Lagrange multipliers (an independent route), displacements and
    interface forces to 1e-8."""
    bodies = _three_layers()
    A = [assemble_body(b) for b in bodies]
    cps = _pairings(bodies)
    assert [c.pairing.coupling for c in cps] == ["mortar", "mortar"]
    rm = reduce_bodies(A, cps)
    # full constraint matrix: G over all DOFs of all bodies
    offs = np.concatenate([[0], np.cumsum([a.n_dofs for a in A])])
    G = rm.G.tocoo()
    body = np.searchsorted(rm.offsets, G.col, side="right") - 1
    dim = 2
    node_pos, comp = (G.col - rm.offsets[body]) // dim, (G.col - rm.offsets[body]) % dim
    nodes = [b.C[::dim] // dim for b in rm.bodies]
    col = offs[body] + dim * np.array([nodes[b][k] for b, k in zip(body, node_pos)]) + comp
    Gf = sp.csr_matrix((G.data, (G.row, col)), shape=(G.shape[0], offs[-1]))
    K = sp.block_diag([a.K for a in A], format="csr")
    F = np.concatenate([a.loads.get("preload", np.zeros(a.n_dofs)) for a in A])
    free = np.setdiff1d(np.arange(offs[-1]), np.concatenate([o + a.fixed
                                                             for o, a in zip(offs, A)]))
    Kf = K[free][:, free]
    kappa = Kf.diagonal().mean()         # constraint rows scaled to the stiffness
    Gff = kappa * Gf[:, free]
    saddle = sp.bmat([[Kf, Gff.T], [Gff, None]], format="csc")
    sol = spla.spsolve(saddle, np.concatenate([F[free], np.zeros(G.shape[0])]))
    x = np.zeros(offs[-1])
    x[free] = sol[:len(free)]
    lam_full = -kappa * sol[len(free):]  # K x = F + G^T lam: the multiplier is -lam
    u = np.concatenate(rm.recover(np.zeros(rm.K.shape[0]), [1.0]))
    assert np.abs(u - x).max() < 1e-8 * np.abs(x).max()
    lam = rm.W[:, 0]
    assert np.abs(lam - lam_full).max() < 1e-8 * np.abs(lam).max()


def test_three_bodies_preload_with_a_friction_coefficient_per_interface():
    bodies = _three_layers()
    A = [assemble_body(b) for b in bodies]
    cps = _pairings(bodies)
    rm = reduce_bodies(A, cps)
    mu = np.concatenate([np.full(c.pairing.n_pairs, m_) for c, m_ in zip(cps, (0.6, 0.2))])
    prob = ContactProblem(rm.K, mu, dim=2)
    lam_w = rm.welded_contact_force([1.0])
    res = contact_solve(prob, lam_w)
    assert res.success and residual(prob, lam_w, res.d, res.lam) <= 1e-8
    # the bolts press all three plates together: both interfaces carry the bolt load
    bolt = 17.554e6 * 0.00635
    for k in range(2):
        sl = slice(rm.rows[k], rm.rows[k + 1])
        assert res.lam[sl, -1].sum() == pytest.approx(bolt, rel=1e-3)
        assert (res.status[sl] != 2).any()


def test_body_in_no_interface_is_refused():
    bodies = _three_layers()
    A = [assemble_body(b) for b in bodies]
    cps = _pairings(bodies)[:1]
    with pytest.raises(InputError, match="body 'top' belongs to no interface.*Fix"):
        reduce_bodies(A, cps)


def test_three_bodies_functional_equals_the_recovered_fields():
    bodies = _three_layers()
    A = [assemble_body(b) for b in bodies]
    rm = reduce_bodies(A, _pairings(bodies))
    rng = np.random.default_rng(5)
    ls = [rng.normal(size=a.n_dofs) for a in A]
    rm = rm.with_functionals({"l": ls})
    d = rng.normal(size=rm.K.shape[0]) * 1e-8
    u = rm.recover(d, [1.0])
    assert rm.evaluate("l", d, [1.0]) == pytest.approx(sum(l @ x for l, x in zip(ls, u)),
                                                       rel=1e-9)
