"""Scene specs and the seeded generator."""

import json

import numpy as np
import pytest

from tabletop.errors import SceneError
from tabletop.sim.generator import PLACEMENT_REGION
from tabletop.sim.scene import (
    ObjectSpec,
    SceneSpec,
    list_default_scenes,
    load_scene_spec,
)


def test_shipped_scenes_load_and_have_ambiguous_duplicates():
    assert {"default", "random"} <= set(list_default_scenes())
    for name in list_default_scenes():
        spec = load_scene_spec(name)
        kinds = [o.kind for o in spec.objects]
        dup = {k for k in kinds if kinds.count(k) > 1}
        assert dup, f"{name}: no duplicated kind"
        for k in dup:
            colors = [o.color for o in spec.objects if o.kind == k]
            assert len(set(colors)) == len(colors), f"{name}: duplicates of {k} share a colour"


def test_default_scene_has_named_areas_including_the_tray():
    spec = load_scene_spec("default")
    tray = spec.object("tray")
    area = spec.area("tray area")
    lo, hi = tray.aabb()
    assert area.contains(((lo + hi) / 2)[None, :2]).all()
    assert spec.area("left").center[1] > 0 > spec.area("right").center[1]
    assert spec.area("front").center[0] > spec.area("back").center[0]
    with pytest.raises(SceneError, match="areas: .*left side of the table"):
        spec.area("on the ceiling")


def test_generator_is_deterministic_and_seed_dependent(tmp_path):
    def draw(seed):
        p = tmp_path / f"s{seed}.toml"
        p.write_text(f"[random]\nseed = {seed}\ncount = 9\nduplicates = 2\n")
        return load_scene_spec(p)

    a, b, c = draw(3), draw(3), draw(4)
    assert a.objects == b.objects
    assert a.objects != c.objects
    kinds = [o.kind for o in a.objects]
    assert sum(kinds.count(k) == 2 for k in set(kinds)) == 2


@pytest.mark.parametrize("seed", range(8))
def test_generated_objects_are_placeable_and_apart(tmp_path, seed):
    p = tmp_path / "s.toml"
    p.write_text(f"[random]\nseed = {seed}\ncount = 10\nduplicates = 2\n")
    spec = load_scene_spec(p)  # SceneSpec itself rejects overlaps and overhangs
    assert len(spec.objects) == 10
    for o in spec.objects:
        lo, hi = o.aabb()
        assert PLACEMENT_REGION["x"][0] <= lo[0] and hi[0] <= PLACEMENT_REGION["x"][1]
        assert np.hypot(hi[0], max(abs(lo[1]), abs(hi[1]))) <= PLACEMENT_REGION["r"][1] + 1e-9


def test_spec_round_trips_through_dict(tmp_path):
    spec = load_scene_spec("random")
    p = tmp_path / "explicit.json"
    p.write_text(json.dumps(spec.to_dict()))
    again = load_scene_spec(p)
    assert again.objects == spec.objects
    assert again.areas == spec.areas


def test_errors_name_the_problem_and_options(tmp_path):
    with pytest.raises(SceneError, match="valid kinds: .*'duck'"):
        ObjectSpec("x", "unicorn", "red", (0.5, 0.0))
    with pytest.raises(SceneError, match="valid: .*'blue'"):
        ObjectSpec("x", "mug", "chartreuse", (0.5, 0.0))
    with pytest.raises(SceneError, match="a mug may be"):
        ObjectSpec("x", "mug", "brown", (0.5, 0.0))
    a = ObjectSpec("a", "mug", "red", (0.5, 0.0))
    b = ObjectSpec("b", "mug", "blue", (0.52, 0.01))
    with pytest.raises(SceneError, match="'a' and 'b' overlap"):
        SceneSpec(objects=(a, b))
    with pytest.raises(SceneError, match="overhangs the table"):
        SceneSpec(objects=(ObjectSpec("a", "mug", "red", (0.79, 0.0)),))
    with pytest.raises(SceneError, match="repeated: \\['a'\\]"):
        SceneSpec(objects=(a, ObjectSpec("a", "duck", "yellow", (0.3, 0.3))))
    bad = tmp_path / "bad.toml"
    bad.write_text("[[objects]]\nname = 'm'\nkind = 'mug'\n")
    with pytest.raises(SceneError, match="missing required field 'color'"):
        load_scene_spec(bad)
    bad.write_text("[sceen]\nname = 'x'\n")
    with pytest.raises(SceneError, match="unknown sections \\['sceen'\\]"):
        load_scene_spec(bad)
    with pytest.raises(SceneError, match="shipped scenes: .*default"):
        load_scene_spec(tmp_path / "nope.toml")
    bad.write_text("[random]\nseed = 1\ncount = 40\n")
    with pytest.raises(SceneError, match="no free place"):
        load_scene_spec(bad)


def test_textured_kinds_take_only_the_colour_their_texture_shows():
    """A kind that keeps its texture renders the same in any colour: giving it two colours
    would make labels ("the blue jenga block") that no camera can see."""
    from tabletop.sim.catalog import OBJECT_KINDS

    textured = {k: v.colors for k, v in OBJECT_KINDS.items() if v.keep_texture}
    assert textured, "the catalogue has textured kinds (jenga block, domino, ball, tray)"
    assert {k: c for k, c in textured.items() if len(c) != 1} == {}
    assert textured["jenga_block"] == ("brown",) and textured["domino"] == ("black",)
