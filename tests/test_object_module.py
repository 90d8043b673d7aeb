"""The object module on a synthetic map: the right box, the background, the margin."""

import numpy as np
import pytest
from module_helpers import GRID, judge_at, labelled_voxels, text_encoder

from tabletop.errors import ConfigError
from tabletop.mapping.object_module import ObjectConfig, ObjectModule
from tabletop.mapping.targets import max_position

BOXES = {
    "red mug": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.10)),
    "yellow duck": ((0.40, 0.10, 0.01), (0.46, 0.16, 0.07)),
}


@pytest.fixture(scope="module")
def module():
    return ObjectModule(labelled_voxels(BOXES), text_encoder())


def test_a_query_lands_on_its_box_and_heat_decays_from_it(module):
    h = module.heatmap("yellow duck", 10.0, judge_at(0.1))
    assert h.found and h.modality == "object" and h.peak == pytest.approx(1.0)
    p = max_position(h, module.voxels.occupancy())
    lo, hi = BOXES["yellow duck"]
    assert np.all(p >= np.subtract(lo, 0.01)) and np.all(p <= np.add(hi, 0.01))
    # heat is 0 beyond 1/decay = 10 cm from the box
    far = GRID.world_to_index(np.array([[0.13, -0.17, 0.05]]))[0][0]
    assert h.values[tuple(far)] == 0.0


def test_the_background_and_the_calibration_can_refuse(module):
    h = module.heatmap("table", 10.0, judge_at(0.1))  # a background concept is no object
    assert not h.found and h.reason and h.peak == 0.0
    strict = module.heatmap("yellow duck", 10.0, judge_at(5.0))
    assert not strict.found and "weak" in strict.reason and strict.evidence > 0


def test_features_follow_the_voxels():
    vm = labelled_voxels({"red mug": BOXES["red mug"]})
    m = ObjectModule(vm, text_encoder())
    n = len(m.features())
    vm.integrate(np.array([[0.5, 0.2, 0.15]]), np.zeros((1, vm.dim), np.float32))
    assert len(m.features()) == n + 1  # the cache was refreshed


def test_config_is_checked():
    with pytest.raises(ConfigError, match="select_margin"):
        ObjectConfig(select_margin=2.0)
    with pytest.raises(ConfigError, match="background"):
        ObjectConfig(background=())
