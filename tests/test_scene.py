"""Scene specs and the seeded generator."""

import json

import numpy as np
import pytest

from tabletop.errors import SceneError
from tabletop.sim.generator import CLUTTER_REGION, LOW_KINDS, PLACEMENT_REGION, TALL_KINDS
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


def _clutter(seed: int, count: int = 12) -> SceneSpec:
    r = {"seed": seed, "count": count, "duplicates": 3, "profile": "clutter"}
    return SceneSpec.from_dict({"random": r}, source=f"clutter-{seed}")


def _gap(a: ObjectSpec, b: ObjectSpec) -> float:
    """Horizontal distance [m] between two objects' boxes (0 when they touch)."""
    (la, ha), (lb, hb) = a.aabb(), b.aabb()
    return float(np.linalg.norm(np.maximum(0.0, np.maximum(la[:2] - hb[:2], lb[:2] - ha[:2]))))


@pytest.mark.parametrize("seed", [950, 951, 952, 953, 5])
def test_clutter_profile_packs_a_dense_table_with_tall_objects_beside_low_ones(seed):
    spec = _clutter(seed)  # SceneSpec itself rejects overlaps and overhangs
    objs = spec.objects
    kinds = [o.kind for o in objs]
    assert len(objs) == 12
    assert sum(kinds.count(k) == 2 for k in set(kinds)) >= 3  # duplicated kinds
    tall = [o for o in objs if o.kind in TALL_KINDS]
    low = [o for o in objs if o.kind in LOW_KINDS]
    assert len(tall) >= 3 and len(low) >= 3 and "tray" not in kinds
    for o in objs:
        lo, hi = o.aabb()
        assert CLUTTER_REGION["x"][0] <= lo[0] and hi[0] <= CLUTTER_REGION["x"][1]
        assert max(abs(lo[1]), abs(hi[1])) <= CLUTTER_REGION["y_abs"]
    # dense: every object has a neighbour within 7 cm, and a low one stands beside a tall one
    assert max(min(_gap(a, b) for b in objs if b is not a) for a in objs) < 0.07
    assert min(_gap(a, b) for a in low for b in tall) < 0.05
    # the same seed draws the same table; another seed another one
    assert _clutter(seed).objects == objs and _clutter(seed + 1).objects != objs


def test_clutter_profile_is_denser_than_the_table_profile():
    def spread(spec) -> float:
        """Area [m^2] of the bounding box of the objects' centres."""
        xy = np.array([o.position for o in spec.objects])
        return float(np.prod(xy.max(axis=0) - xy.min(axis=0)))

    table = [
        SceneSpec.from_dict({"random": {"seed": s, "count": 12, "duplicates": 3}}) for s in range(4)
    ]
    clutter = [_clutter(s) for s in range(4)]
    assert max(map(spread, clutter)) < 0.7 * min(map(spread, table))


def test_unknown_profile_names_the_field_and_the_profiles():
    with pytest.raises(SceneError, match="random.profile: unknown profile 'dense'.*'clutter'"):
        SceneSpec.from_dict({"random": {"seed": 1, "profile": "dense"}})


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
