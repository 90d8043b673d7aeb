"""The 10 cm success criterion against a ground-truth point or box."""

import numpy as np
import pytest

from tabletop.arm.obstacles import Box
from tabletop.arm.success import SUCCESS_RADIUS_M, distance_to_box, reach_success
from tabletop.errors import ConfigError
from tabletop.transforms import rotation_about


def test_point_criterion_is_inclusive_at_10cm():
    assert SUCCESS_RADIUS_M == 0.10
    assert reach_success([0.5, 0.0, 0.2], point=[0.5, 0.0, 0.1]).success
    r = reach_success([0.5, 0.0, 0.2001], point=[0.5, 0.0, 0.1])
    assert not r.success and r.distance_m == pytest.approx(0.1001)


def test_box_distance_is_zero_inside_and_euclidean_outside():
    box = Box([0.5, 0.0, 0.05], [0.05, 0.02, 0.05], rotation_about("z", np.pi / 2))
    assert distance_to_box([0.5, 0.0, 0.05], box) == 0.0
    assert distance_to_box([0.5, 0.0, 0.2], box) == pytest.approx(0.1)
    assert distance_to_box([0.5, 0.08, 0.05], box) == pytest.approx(0.03)  # rotated extents
    assert reach_success([0.5, 0.0, 0.19], box=box).success


def test_exactly_one_ground_truth_is_required():
    with pytest.raises(ConfigError, match="exactly one ground truth"):
        reach_success([0, 0, 0])
    with pytest.raises(ConfigError, match=r"tcp must be a finite \(3,\) point"):
        reach_success([0, 0], point=[0, 0, 0])
