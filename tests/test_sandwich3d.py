"""sandwich-3d end to end (docs/validation.md): the benchmark's checks, results files."""
import json

import meshio
import numpy as np
import pytest

import qsma
from qsma.contact import ContactProblem, residual
from qsma.examples import sandwich_3d
from qsma.output.files import write_all


@pytest.fixture(scope="module")
def run3d(tmp_path_factory):
    res = qsma.run(sandwich_3d(1))
    out = tmp_path_factory.mktemp("s3d")
    write_all(res, out)
    return res, out


def test_model_sizes():
    m = sandwich_3d(1)
    assert m.n_nodes == 10710
    from qsma.model import make_pairing
    p = make_pairing(m)
    assert p.n_pairs == 561
    assert np.allclose(p.frames[:, 0], [1, 0, 0]) and np.allclose(p.frames[:, 1], [0, 0, 1])
    assert np.allclose(p.frames[:, 2], [0, 1, 0])


def test_spec_checks(run3d):
    r, _ = run3d
    assert r.success and r.n_levels == 51
    stuck = np.flatnonzero(np.cumsum(r.n_slip) == 0)
    assert len(stuck) >= 3
    assert np.all(np.abs(r.f_hz[stuck] / r.f0_hz - 1) < 1e-6)
    assert np.all(np.abs(r.zeta[stuck]) < 1e-8)
    assert np.all(r.zeta >= -1e-8) and np.all(r.dissipation >= -1e-8 * r.dissipation.max())
    assert np.all(np.diff(r.f_hz) <= 1e-8 * r.f0_hz)
    assert np.all(r.n_stuck + r.n_slip + r.n_open == 561)
    assert r.n_slip[-1] > 0 and r.zeta[-1] > 0


def test_every_level_satisfies_the_residual(run3d):
    r, _ = run3d
    problem = ContactProblem(r.reduced.K, r.model_info["mu"], dim=3)
    for k in range(0, r.n_levels, 5):
        g = r.backbone_index[k]                 # the ramp's history is its previous point
        prev = r.backbone_states.state(g - 1) if g else r.preload.state
        lam_w = r.reduced.welded_contact_force([1.0, r.alpha[k]])
        assert residual(problem, lam_w, r.states.d[k], r.states.lam[k], prev) <= 1e-8


def test_friction_cone_respected_in_3d(run3d):
    r, _ = run3d
    lam = r.states.lam[-1]
    P = lam[:, 2]
    Q = np.linalg.norm(lam[:, :2], axis=1)
    closed = r.states.status[-1] != 2
    assert np.all(Q[closed] <= 0.6 * P[closed] * (1 + 1e-7) + 1e-9 * P.max())
    slip = r.states.status[-1] == 1
    assert np.allclose(Q[slip], 0.6 * P[slip], rtol=1e-6)


def test_results_files_3d(run3d):
    r, out = run3d
    data = json.loads((out / "results.json").read_text())
    assert data["model"]["n_pairs"] == 561 and data["model"]["dim"] == 3
    assert len(data["levels"]["zeta"]) == 51
    m = meshio.read(out / "fields.vtu")
    assert len(m.points) == 10710 and m.cells[0].type == "hexahedron"
    assert m.point_data["u_level50"].shape == (10710, 3)
    assert (out / "interface_map.png").read_bytes()[:4] == b"\x89PNG"
