"""The arm benchmark runs end to end on a few targets and reports every key (not timed)."""

import numpy as np

from tabletop.arm.bench import GoalAudit, audit_goal, cluttered_scene, run_arm_benchmark
from tabletop.arm.collision import CollisionChecker
from tabletop.arm.model import PandaModel
from tabletop.arm.obstacles import Box, Cylinder

KEYS = {
    "reach_within_1cm",
    "object_within_10cm",
    "contacts",
    "ik_step_ms_median",
    "ik_step_ms_p95",
    "collision_check_ms_median",
    "collision_check_ms_p95",
    "ik_plus_collision_ms_median",
    "dls_iter_ms_median",
    "mink_over_dls_ratio",
    "reasons",
    "probes_right_reason",
    "reachable",
    "reachable_by_audit",
    "reachable_by_controller",
    "missed_reachable",
    "infeasible_by_audit",
    "goal_search_ms_median",
    "goal_search_ms_p95",
    "routes",
    "fallback_share",
    "fallback_reached",
    "alternative_goals",
    "planning_ms_median",
    "planning_ms_p95",
}


def test_cluttered_scene_is_seeded_and_on_the_table():
    a = cluttered_scene(np.random.default_rng(3))
    b = cluttered_scene(np.random.default_rng(3))
    assert len(a) == 7 and a[0].name == "table"
    for x, y in zip(a[1:], b[1:], strict=True):
        np.testing.assert_array_equal(x.center, y.center)
        assert isinstance(x, Box | Cylinder)
        assert 0.3 <= x.center[0] <= 0.7 and abs(x.center[1]) <= 0.4


def test_small_benchmark_reports_every_key():
    out = run_arm_benchmark(n_targets=8, seed=1)
    assert KEYS <= set(out)
    assert out["contacts"] == 0
    assert out["probes_right_reason"] == "6/6"
    assert sum(out["reasons"].values()) == 8
    assert sum(out["routes"].values()) == 8
    assert 0.0 <= out["fallback_share"] <= 1.0
    assert out["reach_within_1cm"] >= 0.85
    assert out["reachable"] == out["reachable_by_audit"]
    assert out["reachable_by_audit"] == out["reachable_by_controller"] + out["missed_reachable"]


def test_audit_finds_a_configuration_the_first_goal_check_missed():
    """Benchmark seed 0, target 116 (beside box3): the first goal check called it blocked."""
    scene = cluttered_scene(np.random.default_rng(0))
    model = PandaModel()
    checker = CollisionChecker(model, scene)
    audit = audit_goal(model, checker, [0.586, 0.2344, 0.04], n_random=20)
    assert isinstance(audit, GoalAudit) and audit.feasible
    assert checker.clearance(audit.q).distance >= 0.01
    np.testing.assert_allclose(model.fk(audit.q)[:3, 3], [0.586, 0.2344, 0.04], atol=1e-3)
    far = audit_goal(model, checker, [0.8, 0.6, 0.7], n_random=3, n_yaw=2, climb_iters=5)
    assert not far.feasible and far.converged == 0 and far.q is None
