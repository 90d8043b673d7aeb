"""PyBullet's EGL renderer keeps one scene per process: a second world renders with
TinyRenderer instead of turning the first world's pictures into its own scene."""

import numpy as np
import pybullet as pb
import pytest

from tabletop.errors import SimulationError
from tabletop.eval.harness import generated_scene
from tabletop.sim.scene import load_scene_spec
from tabletop.sim.world import SimWorld, egl_holder
from tabletop.transforms import make_transform

#: Straight down at the table from 0.8 m.
T_DOWN = make_transform(np.diag([1.0, -1.0, -1.0]), (0.45, 0.0, 0.8))


def test_a_second_world_does_not_change_what_the_first_renders():
    with SimWorld(load_scene_spec("default")) as a:
        before = a.render(T_DOWN).rgb.copy()
        with SimWorld(generated_scene(5)) as b:
            after = a.render(T_DOWN).rgb
            theirs = b.render(T_DOWN)
            # the first world still shows its own scene, the second its own
            assert np.abs(after.astype(int) - before).mean() < 1.0
            assert np.abs(theirs.rgb.astype(int) - before).mean() > 5.0
            ids = {o.instance_id for o in b.ground_truth().objects}
            assert len(ids & set(np.unique(theirs.segmentation).tolist())) >= 3
            if a.renderer == "egl":
                assert b.renderer == "tiny" and egl_holder(pb) == a._client
                with pytest.raises(SimulationError, match="holds the EGL renderer"):
                    SimWorld(generated_scene(6), renderer="egl")
    # closed, the first world gives the renderer back
    assert egl_holder(pb) is None
