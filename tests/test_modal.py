"""Tied linear modes of sandwich-2d."""
import numpy as np
import pytest

from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.modal import linear_modes, mode_tip, stacked
from qsma.model import make_pairing

# Euler-Bernoulli first clamped-free frequencies with E/(1 - nu^2) (sandwich-2d.md):
F_TWO_BEAMS, F_SOLID = 142.7, 285.3


def _setup(refine):
    m = sandwich_2d(refine)
    return m, [assemble_body(b) for b in m.bodies], make_pairing(m)


def test_sandwich_reference_mesh_sizes():
    m, _, p = _setup(1)
    assert m.n_nodes == 2250 and p.n_pairs == 65
    assert np.allclose(p.normals, [0.0, 1.0]) and np.allclose(p.frames[:, 0], [1.0, 0.0])


def test_tied_first_bending_between_bounds_and_converging():
    rows = []
    for r in (1, 2, 4):
        m, A, p = _setup(r)
        f = linear_modes(m, A, p, n_modes=3).f_hz[0]
        rows.append((r, m.n_nodes, f))
    print("\nrefine  nodes   f1 tied-all [Hz]")
    for r, n, f in rows:
        print(f"{r:6d} {n:6d} {f:12.3f}")
    f = np.array([row[2] for row in rows])
    assert np.all((F_TWO_BEAMS < f) & (f < F_SOLID))
    diffs = np.abs(np.diff(f))
    assert np.all(np.diff(f) < 0)            # stiffness converges from above (locking)
    assert diffs[1] < 0.5 * diffs[0]         # successive changes shrink
    assert diffs[1] / f[-1] < 0.01


def test_untied_is_two_separate_beams():
    m, A, p = _setup(1)
    f = linear_modes(m, A, p, tied=np.zeros(p.n_pairs, bool), n_modes=2).f_hz
    assert f[0] == pytest.approx(f[1], rel=1e-6)          # two identical beams
    assert f[0] == pytest.approx(F_TWO_BEAMS, rel=0.04)    # refine 1, Q1 locking


def test_modes_mass_normalised_and_ties_hold():
    m, A, p = _setup(1)
    md = linear_modes(m, A, p, n_modes=3)
    M = stacked([a.M for a in A])
    G = md.shapes.T @ (M @ md.shapes)
    assert np.abs(G - np.eye(3)).max() < 1e-9
    off = m.dof_offsets()
    for c in range(2):
        u1 = md.shapes[off[0] + 2 * p.nodes1 + c]
        u2 = md.shapes[off[1] + 2 * p.nodes2 + c]
        assert np.abs(u1 - u2).max() == 0.0                # elimination, not penalty
    assert abs(mode_tip(md, m, 0)) > 0


def test_bad_tie_mask_rejected():
    m, A, p = _setup(1)
    with pytest.raises(InputError, match="tied mask"):
        linear_modes(m, A, p, tied=np.ones(3, bool))
