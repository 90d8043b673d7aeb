"""The arm benchmark runs end to end on a few targets and reports every key (not timed)."""

import numpy as np

from tabletop.arm.bench import cluttered_scene, run_arm_benchmark
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
    assert out["reach_within_1cm"] >= 0.85
