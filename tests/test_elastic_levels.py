"""Levels where no pair with friction slipped need no loop: their cycle is elastic
(docs/theory.md "Exact zeros"). The frictionless lap joint (lap-2d with mu = 0: its
pairs open, close and slide from the preload on, so Masing's checks fail at every
level) against the same run with the loop forced at every level, and the lap joint
with friction, whose slipping levels keep their loops."""
import csv

import numpy as np
import pytest

import qsma
from qsma.analysis.levels import Levels
from qsma.examples import lap_2d

LEVELS = Levels.log("tip", 1e-6, 1e-3, 6)


@pytest.fixture(scope="module")
def frictionless():
    model = lap_2d(1, mu=0.0)
    return qsma.run(model, levels=LEVELS), qsma.run(model, levels=LEVELS, dissipation="loop")


def test_frictionless_levels_compute_no_loop_and_dissipate_nothing(frictionless):
    auto, loop = frictionless
    assert auto.success and loop.success
    assert list(auto.dissipation_method) == ["elastic"] * auto.n_levels
    assert all(r.startswith("elastic: no pair with friction slipped") for r in
               auto.method_reason)
    assert auto.solver["loop_solves"] == 0 and not auto.level_costs.loop_solves.any()
    assert np.isnan(auto.f_hz_loop).all() and not auto.loop_cycles.any()
    for column in (auto.dissipation, auto.zeta, auto.dissipation_error):
        assert np.array_equal(column, np.zeros(auto.n_levels))
    # the loops the levels no longer compute: elastic too, at the same frequency (the
    # peak-to-peak secant of the two backbones the cycle retraces; 1.1e-14 measured)
    assert list(loop.dissipation_method) == ["loop"] * loop.n_levels
    assert np.array_equal(loop.dissipation, np.zeros(loop.n_levels))
    np.testing.assert_allclose(auto.f_hz, loop.f_hz, rtol=1e-10)
    np.testing.assert_allclose(auto.tip_velocity, loop.tip_velocity, rtol=1e-10)
    # a stiffening elastic level is information, as with its loop, not Masing forced
    assert auto.flags == loop.flags and any("hardening" in f for f in auto.flags)
    # loops.png draws the cycle the level has: both backbones, there and back
    from qsma.output.plots import loop_curve
    q, alpha, label = loop_curve(auto, auto.n_levels - 1)
    assert label == "elastic cycle (the backbones)"
    assert alpha.max() == auto.alpha[-1] and alpha.min() == -auto.alpha[-1]
    assert q.min() == auto.q_neg[-1] and np.trapezoid(alpha, q) == 0.0


def test_levels_where_a_pair_with_friction_slipped_keep_their_loops():
    res = qsma.run(lap_2d(1), levels=LEVELS)
    assert res.success and res.model_info["mu"] > 0
    slipped = res.n_slip > 0
    assert slipped.sum() >= 2
    assert np.all(res.dissipation_method[slipped] == "loop")
    assert np.all(res.dissipation[slipped] > 0)
    assert np.all(res.level_costs.loop_solves[slipped] > 0)


def test_the_summary_and_the_files_name_the_elastic_levels(tmp_path, capsys):
    from qsma.cli import main
    out = tmp_path / "out"
    assert main(["run", "--example", "lap-2d", "--mu", "0", "--levels",
                 "tip:log:1e-6:1e-3:3", "--out", str(out), "--no-plots", "--no-vtu"]) == 0
    assert "0 level(s) by Masing's rules, 0 by computed loops, 3 elastic without a loop" \
        in capsys.readouterr().out
    with open(out / "results.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["dissipation_method"] for r in rows] == ["elastic"] * 3
    assert all(float(r["dissipation [J/m]"]) == 0.0 for r in rows)
