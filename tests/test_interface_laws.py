"""Interface laws: the compliant layer in series with the Coulomb slider.

Closed forms (the layer alone, a Jenkins element with a stick stiffness), exactness of
the slider's problem, the law residual of nonlinear laws, consistency of the tied modes
with the ramps, convergence to the rigid law, and bad input.
"""
import dataclasses

import numpy as np
import pytest

from qsma.reduction.two_bodies import reduce_two_bodies
from qsma.contact import ContactProblem, ContactState, solve
from qsma.contact.laws import (ElasticStick, ExponentialPressure, InterfaceLaw,
                               LinearPressure, TabularPressure, law_from_table)
from qsma.contact.layer import Layer, series_stiffness, solve_layered
from qsma.contact.pairlaws import PairLaws
from qsma.errors import InputError
from qsma.fe import assemble_body
from qsma.model import Body, Clamp, Interface, LinearDamping, Material, Model, make_pairing
from qsma.mesh.generate import structured_mesh

LAWS = [LinearPressure(2e13), ExponentialPressure(2e-6, 5e6),
        ExponentialPressure(1e-5, 1e8),
        TabularPressure(((0.0, -1e-6), (1e6, 0.0), (5e6, 1e-6), (2e7, 2e-6)))]


@pytest.mark.parametrize("law", LAWS, ids=lambda law: law.name)
def test_pressure_overclosure_inverse_and_tangent(law):
    """``overclosure`` inverts ``pressure`` above the onset and ``stiffness`` is its
    derivative (central differences, away from the kinks of the table)."""
    h = np.linspace(law.onset, law.onset + 5e-6, 41)[1:]
    p = law.pressure(h)
    assert np.all(np.diff(p) > 0) and law.pressure(law.onset - 1e-7) == 0
    assert np.allclose(law.overclosure(p), h, rtol=0, atol=1e-15)
    dh = 1e-12
    fd = (law.pressure(h + dh) - law.pressure(h - dh)) / (2 * dh)
    kinks = np.zeros_like(h, bool)
    if law.name == "tabular":
        nodes = np.array(law.table)[:, 1]
        kinks = np.min(np.abs(h[:, None] - nodes[None]), axis=1) < 2 * dh
    assert np.allclose(law.stiffness(h)[~kinks], fd[~kinks], rtol=1e-5)
    assert np.allclose(law.tangent_at_pressure(p), law.stiffness(h), rtol=1e-9)


def test_exponential_law_is_abaqus_form():
    """p(0) = p0 and p(-c0) = 0 with zero slope (Abaqus' EXPONENTIAL)."""
    law = ExponentialPressure(2e-6, 5e6)
    assert law.pressure(0.0) == pytest.approx(5e6, rel=1e-14)
    assert law.pressure(-2e-6) == 0.0 and law.stiffness(-2e-6) == 0.0


def test_exponential_law_is_calculix_form():
    """CalculiX's EXPONENTIAL: p = p0 exp(ln(100) h / c0), 1 % of p0 at the clearance c0
    and nothing beyond; a closure at c0 carries any pressure up to p0 / 100."""
    law = ExponentialPressure(2e-6, 5e6, form="calculix")
    assert law.pressure(0.0) == pytest.approx(5e6, rel=1e-14)
    assert law.pressure(-2e-6 + 1e-15) == pytest.approx(5e4, rel=1e-6)
    assert law.pressure(-2e-6 - 1e-9) == 0.0
    h = np.linspace(-1.5e-6, 3e-6, 10)
    assert np.allclose(law.overclosure(law.pressure(h)), h, rtol=0, atol=1e-18)
    assert law.overclosure(1e4) == -2e-6
    assert law_from_table({"normal": "exponential", "clearance": 2e-6,
                           "pressure_at_zero": 5e6, "form": "calculix"}) == InterfaceLaw(law)


@pytest.mark.parametrize("table, fix", [
    ({"normal": "linear"}, "needs ['normal_stiffness']"),
    ({"normal": "linear", "normal_stiffness": -1.0}, "> 0"),
    ({"normal": "springy"}, "choose one of"),
    ({"normal": "hard", "tangential": "elastic"}, "needs ['tangential_stiffness']"),
    ({"normal": "hard", "stiffness": 1e13}, "unknown key"),
    ({"normal": "tabular", "table": [[1e6, 0.0], [2e6, 1e-6]]}, "zero pressure"),
    ({"normal": "tabular", "table": [[0.0, 0.0], [2e6, 1e-6], [1e6, 2e-6]]},
     "increase strictly"),
    ({"normal": "exponential", "clearance": float("nan"), "pressure_at_zero": 1e6},
     "finite"),
])
def test_bad_law_tables_are_refused_with_the_fix(table, fix):
    with pytest.raises(InputError, match=fix.replace("[", r"\[").replace("]", r"\]")):
        law_from_table(table, "interface.law")


def test_law_table_round_trip():
    for law in (InterfaceLaw(LinearPressure(1e14), ElasticStick(3e13)),
                InterfaceLaw(ExponentialPressure(1e-6, 1e7)), InterfaceLaw(LAWS[3])):
        assert law_from_table(law.as_dict()) == law


def _spd(n, seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    return A @ A.T + n * np.eye(n)


@pytest.mark.parametrize("scale", [1e-6, 1e-2, 1.0, 1e2])
def test_series_stiffness_is_the_inverse_of_the_summed_flexibility(scale):
    """``K' = (K^-1 + C)^-1`` (dense reference), rigid components kept, symmetric."""
    K = _spd(12, 1)
    c = np.abs(np.random.default_rng(2).normal(size=12)) * scale / np.diag(K)
    c[[0, 5]] = 0.0                                        # rigid components
    Kp = series_stiffness(K, c)
    J = c > 0
    # with rigid components: K' = (F + C)^-1 on the compliant ones, after the rigid ones
    # are condensed out of the flexibility: compare through a solve instead
    F = np.linalg.inv(K)
    lam = np.random.default_rng(3).normal(size=12)
    d_slider = F @ lam + c * lam                        # slider displacement of lam
    assert np.allclose(Kp @ d_slider, lam, rtol=1e-10, atol=1e-12 * np.abs(lam).max())
    assert np.array_equal(Kp, Kp.T)
    assert series_stiffness(K, np.zeros(12)) is K
    assert np.allclose(series_stiffness(K, c * J), Kp)


# --- the layer alone: two stiff blocks, a cylinder's gap, the layer takes the load --------

E_STIFF = 2e17          # Pa: the blocks hardly deform (1e-4 of the layer's compliance)
R = 0.05                # m, radius of the cylinder's gap x^2 / (2R)


def _blocks(law):
    xs = np.linspace(-2e-3, 2e-3, 21)
    mat = Material(E_STIFF, 0.3, 7800.0)
    bodies = []
    for name, ys in (("bottom", np.linspace(-1e-3, 0, 4)), ("top", np.linspace(0, 1e-3, 4))):
        m = structured_mesh(xs, ys)
        far = ys[0] if name == "bottom" else ys[-1]
        m = m.with_sets(node_sets={"far": np.flatnonzero(np.abs(m.points[:, 1] - far)
                                                         < 1e-12)},
                        facet_sets={"contact": m.boundary_facets_where(
                            lambda p: np.abs(p[:, 1]) < 1e-12)})
        bodies.append(Body(name, m, mat, clamps=(Clamp("far"),)))
    itf = Interface("bottom", "contact", "top", "contact", law=law,
                    gap=lambda x: x[:, 0] ** 2 / (2 * R))
    model = Model(tuple(bodies), itf, mu=0.3)
    pairing = make_pairing(model)
    red = reduce_two_bodies(assemble_body(bodies[0]), assemble_body(bodies[1]), pairing)
    from qsma.model.pairing import pair_gaps, pair_laws
    physical = ContactProblem(red.K, 0.3, gap0=pair_gaps(model, pairing, 1e-9), dim=2)
    return model, pairing, physical, pair_laws(model, pairing)


def _shifted(layer, r):
    """The slider's welded force of a rigid shift ``r`` (n_pairs, dim) of the top block:
    ``lam = K (d - r)`` for the bodies, so ``lam = K' (d' - r)`` for the slider."""
    return -(layer.problem.K @ r.ravel()).reshape(r.shape)


def _layer_solve(layer, lam_w, state=None):
    def once(load, st, gs):
        return solve(layer.problem, load, st, guess=gs)
    return solve_layered(layer, once, lam_w, state)


def test_linear_layer_press_and_shift_per_pair():
    """Press the stiff blocks together by ``delta`` and shift them by ``s``: each pair
    of the layer carries ``P = A k_n (delta - x^2/2R)+`` and ``Q = min(A k_t s, mu P)``
    (the blocks' compliance is 1e-4 of the layer's)."""
    kn, kt, mu = 2e13, 1e13, 0.3
    model, pairing, physical, laws = _blocks(InterfaceLaw(LinearPressure(kn),
                                                           ElasticStick(kt)))
    layer = Layer(physical, laws)
    x, A = pairing.x[:, 0], pairing.area
    delta, s = 1e-5, 5e-6
    r = np.zeros((pairing.n_pairs, 2))
    r[:, 1] = -delta
    pressed = _layer_solve(layer, _shifted(layer, r))
    assert pressed.success
    P_exact = A * kn * np.maximum(delta - x ** 2 / (2 * R), 0.0)
    assert np.allclose(pressed.P, P_exact, rtol=2e-3, atol=2e-3 * P_exact.max())
    r[:, 0] = s
    shifted = _layer_solve(layer, _shifted(layer, r), pressed.state)
    assert shifted.success
    Q_exact = np.minimum(A * kt * s, mu * P_exact)
    assert np.allclose(np.abs(shifted.Q[:, 0]), Q_exact, rtol=2e-3,
                       atol=2e-3 * Q_exact.max())
    on = P_exact > 1e-6 * P_exact.max()             # not the pairs just touching
    slips = A * kt * s > mu * P_exact
    assert slips[on].any() and (~slips[on]).any()   # both states present
    assert np.array_equal(shifted.status[on] == 1, slips[on])


def test_exponential_layer_satisfies_its_law_at_every_pair():
    """A nonlinear law: every pair's pressure is the law's at its overclosure, to the
    tolerance, and the result reports its law residual."""
    law = ExponentialPressure(2e-6, 5e6)
    model, pairing, physical, laws = _blocks(InterfaceLaw(law))
    layer = Layer(physical, laws)                # linearised at the law's own p0
    r = np.zeros((pairing.n_pairs, 2))
    r[:, 1] = -4e-6
    res = _layer_solve(layer, _shifted(layer, r))
    assert res.success and res.law_residual <= 1e-10
    h = -(res.d[:, 1] + physical.gap0)
    P_law = pairing.area * law.pressure(h)
    assert np.allclose(res.P, P_law, rtol=1e-9, atol=1e-9 * res.P.max())
    # the contact reaches past where the surfaces touch: clearance up to c0 carries load
    assert np.count_nonzero(res.P > 0) > np.count_nonzero(h > 0)


def test_calculix_exponential_layer_satisfies_its_law():
    """The same blocks with CalculiX's exponential law: every pair on the law's graph,
    the pairs at the clearance c0 anywhere on its vertical segment."""
    law = ExponentialPressure(2e-6, 5e6, form="calculix")
    model, pairing, physical, laws = _blocks(InterfaceLaw(law))
    layer = Layer(physical, laws)
    r = np.zeros((pairing.n_pairs, 2))
    r[:, 1] = -3e-6
    res = _layer_solve(layer, _shifted(layer, r))
    assert res.success and res.law_residual <= 1e-10
    h = -(res.d[:, 1] + physical.gap0)
    on_curve = h > -2e-6 + 1e-12
    assert np.allclose(res.P[on_curve], pairing.area[on_curve] * law.pressure(h[on_curve]),
                       rtol=1e-8)
    assert np.all(res.P[~on_curve] <= pairing.area[~on_curve] * 5e4 * (1 + 1e-9))


def test_jenkins_loop_energy_with_stick_stiffness():
    """One pair: structure spring ``k_s`` in series with a stick stiffness ``k_t`` and a
    slider of limit ``mu N``. A displacement cycle of amplitude ``U`` at the structure's
    end dissipates ``4 mu N (U - mu N / k)`` with ``k = (1/k_s + 1/k_t)^-1``."""
    ks, kn, kt, mu, N, U = 3e8, 5e8, 1e8, 0.4, 1000.0, 1e-5
    physical = ContactProblem(np.diag([ks, kn]), mu, dim=2)
    laws = PairLaws((InterfaceLaw(None, ElasticStick(kt)),), np.zeros(1, int),
                    np.ones(1), 2)
    layer = Layer(physical, laws)
    n = 400
    path = np.concatenate([np.linspace(0, U, n), np.linspace(U, -U, 2 * n)[1:],
                           np.linspace(-U, U, 2 * n)[1:]])
    state, forces = None, []
    for u in path:
        lam_w = np.array([[ks * u, N]])           # far end moved by u, normal push N
        W = layer.welded_basis(lam_w.reshape(-1, 1)).reshape(1, 2)
        res = _layer_solve(layer, W, state)
        assert res.success
        state = res.state
        forces.append(res.Q[0, 0])
    f = np.array(forces)
    cycle = slice(n - 1, None)
    D = np.trapezoid(f[cycle], path[cycle])     # lam_w = k_s u: lam follows the drive
    k = 1 / (1 / ks + 1 / kt)
    F = mu * N
    assert D == pytest.approx(4 * F * (U - F / k), rel=2e-3)
    assert np.abs(f).max() == pytest.approx(F, rel=1e-9)


# --- whole runs ----------------------------------------------------------------------------

def _sandwich(law, **kw):
    from qsma.examples import sandwich_2d
    m = sandwich_2d(refine=1)
    return dataclasses.replace(m, interface=dataclasses.replace(m.interface, law=law), **kw)


def _run(model, levels="tip:log:1e-6:1e-3:7"):
    import qsma
    from qsma.analysis.levels import Levels
    kind, spacing, a, b, n = levels.split(":")
    return qsma.run(model, dissipation="masing",
                    levels=Levels.log(kind, float(a), float(b), int(n)))


def test_compliant_sandwich_stuck_levels_are_the_tied_mode():
    """With a linear layer the tied modes hold the closed pairs by the layer's springs:
    at the first level, where every closed pair sticks, the secant frequency is f0."""
    law = InterfaceLaw(LinearPressure(5e13), ElasticStick(2e13))
    res = _run(_sandwich(law))
    assert res.success and res.n_slip[0] == 0
    assert res.f_hz[0] == pytest.approx(res.f0_hz, rel=1e-9)
    assert res.zeta[0] == 0.0
    assert res.model_info["interface_laws"][0]["normal"] == "linear"


def test_convergence_to_the_rigid_law():
    """As the layer stiffens (k_n = k_t = k) f0 and the damping of a microslip level tend
    to the rigid law's, with an error falling like 1/k (measured: f0 212.5030, 212.5400,
    212.5439 Hz against 212.5443; rates per decade 0.985 and 0.998 for f0, 1.078 and
    0.993 for zeta at the fifth level)."""
    from qsma.examples import sandwich_2d
    rigid = _run(sandwich_2d(refine=1))
    errs = []
    for k in (1e15, 1e16, 1e17):
        r = _run(_sandwich(InterfaceLaw(LinearPressure(k), ElasticStick(k))))
        errs.append((abs(r.f0_hz - rigid.f0_hz), abs(r.zeta[4] - rigid.zeta[4])))
    errs = np.array(errs)
    rates = -np.diff(np.log10(errs), axis=0)
    assert np.all(rates > 0.9) and np.all(rates < 1.15), rates


def test_tied_modes_with_springs_substructured_and_assembled_agree():
    """The tied modes of a compliant layer: through the condensed bodies (springs added to
    the interface block) and through the assembled stiffness with the springs as
    elements, the same frequencies to 1e-9."""
    from qsma.analysis import prepare
    from qsma.modal import linear_modes
    from qsma.contact.layer import interface_springs
    from qsma.analysis.options import RunOptions
    from qsma.analysis import StageClock
    law = InterfaceLaw(LinearPressure(5e13), ElasticStick(2e13))
    p = prepare(_sandwich(law))
    reduced, layer, pre = p.preloaded(RunOptions(), StageClock())
    closed = pre.status != 2
    springs = interface_springs(layer, closed)
    a = linear_modes(p.model, p.assembled, p.pairing, tied=closed, n_modes=3,
                     reduced=reduced, springs=springs)
    b = linear_modes(p.model, p.assembled, p.pairing, tied=closed, n_modes=3,
                     springs=springs)
    assert np.allclose(a.f_hz, b.f_hz, rtol=1e-9)
    rigid = linear_modes(p.model, p.assembled, p.pairing, tied=closed, n_modes=3)
    assert np.all(a.f_hz < rigid.f_hz)            # the springs soften the same contact


def test_linear_damping_is_reported_and_added():
    from qsma.examples import sandwich_2d
    base = sandwich_2d(refine=1)
    res = _run(dataclasses.replace(base, damping=LinearDamping(ratio=8.7e-4)))
    assert np.allclose(res.zeta_structure, 8.7e-4)
    assert np.allclose(res.zeta_total, res.zeta + 8.7e-4)
    ray = LinearDamping(alpha=2.0, beta=1e-6)
    w = 2 * np.pi * 200.0
    assert ray.zeta(w) == pytest.approx(2.0 / (2 * w) + 1e-6 * w / 2)
    with pytest.raises(InputError, match="percent"):
        LinearDamping(ratio=5.0)
    with pytest.raises(InputError, match="not both"):
        LinearDamping(ratio=0.01, alpha=1.0)


def test_layer_in_the_wrong_units_is_refused():
    """A stiffness given per mm^2 in an SI model (1e-9 of the intended) is no joint."""
    import qsma
    with pytest.raises(InputError, match="unit error"):
        qsma.run(_sandwich(InterfaceLaw(LinearPressure(1e4))), dissipation="masing")


def test_gap_field_from_a_height_map_file(tmp_path):
    """A CSV height map: linear interpolation in 1D (2D model), the gap of 'height'
    samples measured from the highest point, coverage and units checked."""
    from qsma.model import read_gap_field
    f = tmp_path / "gap.csv"
    f.write_text("x,gap\n-0.1,0\n0,1e-6\n0.2,3e-6\n")
    g = read_gap_field(f)
    x = np.array([[-0.05, 0.0], [0.1, 0.0]])
    assert np.allclose(g(x), [0.5e-6, 2e-6], rtol=1e-12)
    f.write_text("x,height\n-0.1,0\n0,1\n0.2,3\n")
    h = read_gap_field(f, scale=1e-6)
    assert np.allclose(h(x), [1.5e-6, 0.0], rtol=1e-12)      # touches first at x = 0.1
    with pytest.raises(InputError, match="outside the samples"):
        g(np.array([[0.3, 0.0]]))
    f.write_text("x,z,gap\n0,0,0\n1,0,1e-6\n0,1,2e-6\n1,1,3e-6\n")
    g2 = read_gap_field(f)                      # a linear field is interpolated exactly
    assert g2(np.array([[0.5, 7.0, 0.5]]))[0] == pytest.approx(1.5e-6, rel=1e-12)
    f.write_text("x,gapp\n0,0\n1,1\n")
    with pytest.raises(InputError, match="header"):
        read_gap_field(f)


def test_gap_field_opens_part_of_the_sandwich():
    """A gap that grows along the interface leaves its far part open after the preload,
    with every pair satisfying the contact law on the gap field (w >= 0, P w = 0)."""
    import qsma
    from qsma.examples import sandwich_2d
    m = sandwich_2d(refine=1)
    x0 = float(np.median(make_pairing(m).x[:, 0]))
    gap = lambda x: np.where(x[:, 0] > x0, 5e-5 * (x[:, 0] - x0) / 0.01, 0.0)
    shaped = dataclasses.replace(m, interface=dataclasses.replace(m.interface, gap=gap))
    flat, curved = _run(m), _run(shaped)
    assert curved.success
    pre = curved.preload
    w = pre.d[:, -1] + gap(curved.pairing.x)
    assert np.all(w >= -1e-12) and np.all(np.abs(pre.P * w) <= 1e-9 * pre.P.max() * 1e-6)
    assert curved.model_info["n_closed_after_preload"] != flat.model_info[
        "n_closed_after_preload"]


def test_unmeasured_gap_field_is_refused():
    with pytest.raises(InputError, match="scale = 1e-6"):
        _run(dataclasses.replace(_sandwich(None), interface=dataclasses.replace(
            _sandwich(None).interface, gap=lambda x: np.full(len(x), 5.0))))


# --- rough surfaces ---------------------------------------------------------------------

def _rough(**kw):
    from qsma.contact.laws import RoughSurface
    args = dict(sigma=3e-6, radius=1.4e-3, density=1.4e6, E=192e9, nu=0.3,
                yield_strength=330e6, hardening=620e6, n_sigma=4.4)
    args.update(kw)
    return RoughSurface(**args)


@pytest.mark.parametrize("plastic", [False, True])
def test_rough_contact_against_its_integral(plastic):
    """The tabulated rough law against the asperity integral by adaptive quadrature
    (scipy.integrate.quad over the gaps of the pairs in contact): pressure within 2e-4
    over the closures that carry 0.1 to 100 MPa."""
    from scipy.integrate import quad
    from qsma.contact.laws.rough import _pair_law
    law = _rough() if plastic else _rough(yield_strength=None, hardening=0.0)
    E_star, G_star = law._moduli()
    for h in (0.4, 0.5, 0.6, 0.7) * np.array(law.z_max):
        def f(z):
            F, _, _ = _pair_law(np.array([h - z]), law.radius, E_star, G_star, law.E,
                                law.nu, law.yield_strength, law.hardening)
            return law._density(z) * F[0]
        p, _ = quad(f, 0.0, min(h, law.z_max), limit=200, epsabs=0, epsrel=1e-10)
        assert law.pressure(h) == pytest.approx(law.density * p, rel=2e-4)


def test_rough_pair_law_is_hertz_below_yield_and_stiffer_unloading():
    """Below 1.9 delta_y a pair is Hertzian; beyond, its force stays below Hertz's (the
    asperity yields) and its elastic unloading is stiffer than the loading tangent."""
    from qsma.contact.laws.rough import _pair_law
    law = _rough()
    E_star, G_star = law._moduli()
    C = 1.295 * np.exp(0.736 * 0.3)
    dy = 2 * (np.pi * C * 330e6 / (4 * E_star)) ** 2 * (2 * law.radius)
    d = np.array([0.5, 1.8, 5.0, 50.0]) * dy
    F, a, k = _pair_law(d, law.radius, E_star, G_star, law.E, law.nu, 330e6, 620e6)
    hertz = 4 / 3 * E_star * np.sqrt(law.radius) * d ** 1.5
    assert np.allclose(F[:2], hertz[:2], rtol=1e-14)
    assert np.all(F[2:] < hertz[2:])
    dd = 1e-6 * d
    F2, _, _ = _pair_law(d + dd, law.radius, E_star, G_star, law.E, law.nu, 330e6, 620e6)
    tangent = (F2 - F) / dd
    assert np.all(k[2:] > tangent[2:])
    p = law.pressure(0.6 * law.z_max)
    assert law.unloading_stiffness(p) > law.tangent_at_pressure(p)


def test_rough_law_in_a_run_freezes_on_its_unloading():
    """A plastic rough law: the preload follows the loading curve (every pair's
    pressure is the law's at its closure), then the ramp's layer is the elastic
    unloading through that state: the first level is the tied mode with those
    springs."""
    law = InterfaceLaw(_rough())
    res = _run(_sandwich(law))
    assert res.success
    pre, p = res.preload, res.pairing
    h = -(pre.d[:, -1])
    assert np.allclose(pre.P, p.area * law.normal.pressure(h), rtol=1e-8,
                       atol=1e-9 * pre.P.max())
    assert res.n_slip[0] == 0 and res.f_hz[0] == pytest.approx(res.f0_hz, rel=1e-9)


def test_nonlinear_layer_is_linear_about_the_preload_in_the_ramps():
    """After the preload a nonlinear elastic layer is frozen on its tangent there (the
    preload itself follows the law exactly): the run succeeds without the flags a
    nonlinear elastic layer raises in the ramps."""
    import qsma
    from qsma.analysis.levels import Levels
    law = InterfaceLaw(ExponentialPressure(2e-6, 1e7), ElasticStick(1e13))
    res = qsma.run(dataclasses.replace(_sandwich(law), mu=2.0),
                   levels=Levels.log("tip", 1e-6, 1e-3, 7))
    assert res.success, res.message
    h = -(res.preload.d[:, -1])
    assert np.allclose(res.preload.P, res.pairing.area * law.normal.pressure(h),
                       rtol=1e-8, atol=1e-9 * res.preload.P.max())
    # the ramps see the layer linear: a nonlinear elastic layer would make the stuck
    # levels nonlinear (flagged stuck_not_linear) and its hardening a negative Masing
    # dissipation
    flags = {f for fl in res.flags for f in fl}
    assert not flags & {"stuck_not_linear", "negative_dissipation", "masing_on_hardening"}
