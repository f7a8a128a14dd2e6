"""Hertz and Cattaneo-Mindlin line contact through the FE, condensation and contact layers.

Two identical elastic blocks, far faces clamped, initial gap g0 = x^2/(2R) (a
cylinder of radius R against a plane, locally). The normal load is applied as a
rigid approach delta of the top clamp, the tangential load as a rigid tangential
shift s of the top clamp; a rigid shift of body 2 by r changes the welded force
by K r, since lam = K (d - r) + lam_w. Half-plane theory (plane strain):

    a = sqrt(4 P R / (pi E*)),   1/E* = 2 (1 - nu^2)/E   (identical materials),
    c = a sqrt(1 - Q/(mu P))     (stick half-width, Cattaneo-Mindlin; identical
                                  materials: no normal-tangential coupling).
P and Q are the computed resultants, so the checks do not depend on the finite
size of the blocks through the load-approach relation.
"""
import numpy as np
import pytest

from qsma.reduction.two_bodies import reduce_two_bodies
from qsma.contact import ContactProblem, residual, solve
from qsma.fe import assemble_body
from qsma.model import Body, Clamp, Interface, Material, Model, make_pairing
from qsma.mesh.generate import graded_axis, structured_mesh

E, NU, R, MU = 70e9, 0.3, 0.05, 0.3
W = H = 0.012           # block width and height [m]
A_TARGET = 0.001        # aimed contact half-width [m]


def _geometric(a, b, n, ratio):
    """n intervals from a to b, sizes growing geometrically by ``ratio`` away from a."""
    w = ratio ** np.arange(n)
    return a + (b - a) * np.concatenate([[0.0], np.cumsum(w) / w.sum()])


def _blocks(n_fine):
    h = 1.6 * A_TARGET / n_fine
    side = _geometric(1.6 * A_TARGET, W / 2, 12, 1.25)
    xs = np.concatenate([-side[::-1], graded_axis((-1.6 * A_TARGET, 1.6 * A_TARGET,
                                                   2 * n_fine))[1:-1], side])
    ny = 14
    ys = _geometric(0.0, H, ny, 1.35)
    ys[1] = min(ys[1], h)
    mat = Material(E, NU, 2700.0)
    bodies = []
    for name, y in (("bottom", -ys[::-1]), ("top", ys)):
        m = structured_mesh(xs, y)
        far = -H if name == "bottom" else H
        eps = 1e-12
        m = m.with_sets(
            node_sets={"far": np.flatnonzero(np.abs(m.points[:, 1] - far) < eps)},
            facet_sets={"contact": m.boundary_facets_where(
                lambda p: (np.abs(p[:, 1]) < eps) & (np.abs(p[:, 0]) < 4.0 * A_TARGET))})
        bodies.append(Body(name, m, mat, clamps=(Clamp("far"),)))
    return Model(tuple(bodies), Interface("bottom", "contact", "top", "contact"))


def _half_width(x, positive):
    """Half-width of the zone where ``positive`` holds, to the midpoint of the edge cell."""
    inside = np.abs(x[positive])
    outside = np.abs(x[~positive])
    edge_in = inside.max()
    edge_out = outside[outside > edge_in].min()
    return 0.5 * (edge_in + edge_out)


def _solve_hertz(n_fine):
    model = _blocks(n_fine)
    p = make_pairing(model)
    A = [assemble_body(b) for b in model.bodies]
    rm = reduce_two_bodies(A[0], A[1], p)       # no external load: clamps move
    x = p.x[:, 0]
    prob = ContactProblem(rm.K, MU, gap0=x ** 2 / (2 * R))
    Estar = E / (2 * (1 - NU ** 2))
    P_target = A_TARGET ** 2 * np.pi * Estar / (4 * R)
    n = p.n_pairs
    e_n = np.tile([0.0, 1.0], n)
    e_t = np.tile([1.0, 0.0], n)
    # approach giving roughly the target load: calibrate once with the welded stiffness
    delta = 1.0
    lw = lambda dl, s: (rm.K @ (dl * e_n - s * e_t)).reshape(n, 2)
    for _ in range(3):     # secant on the (nonlinear) load-approach relation
        r = solve(prob, lw(delta * 1e-6, 0.0))
        P = r.lam[:, 1].sum()
        delta *= P_target / P
    normal = solve(prob, lw(delta * 1e-6, 0.0))
    assert normal.success
    P = normal.lam[:, 1].sum()
    a_fe = _half_width(x, normal.status != 2)
    a_th = np.sqrt(4 * P * R / (np.pi * Estar))
    # tangential shift to Q = 0.5 mu P, from the normal state (history)
    out = {"a": (a_fe, a_th), "h": 1.6 * A_TARGET / n_fine}
    Qt = 0.5 * MU * P
    shear = lambda s: abs(solve(prob, lw(delta * 1e-6, s), normal.state).lam[:, 0].sum())
    s0 = 1e-9
    s1 = s0 * Qt / shear(s0)                  # stuck (initial) tangential stiffness
    q0, q1 = shear(s0), shear(s1)
    for _ in range(6):                        # secant on Q(s) = 0.5 mu P
        s0, s1, q0 = s1, s1 + (Qt - q1) * (s1 - s0) / (q1 - q0), q1
        q1 = shear(s1)
        if abs(q1 - Qt) < 1e-3 * Qt:
            break
    s = s1
    tang = solve(prob, lw(delta * 1e-6, s), normal.state)
    assert tang.success
    assert residual(prob, lw(delta * 1e-6, s), tang.d, tang.lam, normal.state) <= 1e-9
    Q = abs(tang.lam[:, 0].sum())
    closed = tang.status != 2
    c_fe = _half_width(x[closed], tang.status[closed] == 0)
    c_th = a_fe * np.sqrt(1 - Q / (MU * tang.lam[:, 1].sum()))
    out["c"] = (c_fe, c_th)
    out["Q/muP"] = Q / (MU * P)
    return out


@pytest.fixture(scope="module")
def studies():
    return {n: _solve_hertz(n) for n in (16, 32)}


def test_hertz_half_width(studies):
    errs = []
    for n, s in studies.items():
        a_fe, a_th = s["a"]
        err = abs(a_fe - a_th) / a_th
        print(f"n_fine={n}: a_FE={a_fe * 1e3:.4f} mm  a_Hertz={a_th * 1e3:.4f} mm  err={err:.3%}"
              f"  (cell {s['h'] * 1e3:.3f} mm)")
        errs.append(err)
        assert err < 0.05
    assert errs[-1] < errs[0] or errs[-1] < 0.01


def test_cattaneo_mindlin_stick_zone(studies):
    errs = []
    for n, s in studies.items():
        c_fe, c_th = s["c"]
        err = abs(c_fe - c_th) / s["a"][1]
        print(f"n_fine={n}: Q/(mu P)={s['Q/muP']:.3f} c_FE={c_fe * 1e3:.4f} mm  "
              f"c_CM={c_th * 1e3:.4f} mm  err/a={err:.3%}")
        assert 0.2 < s["Q/muP"] < 0.8
        errs.append(err)
        assert err < 0.05
    assert errs[-1] <= errs[0] + 0.005
