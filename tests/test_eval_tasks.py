"""Task files: parsing, validation errors that name the problem, truth resolution, the shipped
suites' coverage. No simulation here."""

import copy
import json

import numpy as np
import pytest
from helpers import ground_truth_dict

from tabletop.eval.report import EvalResult
from tabletop.eval.results import EncoderRun, GoalResult, TaskRun, in_a_row
from tabletop.eval.suites import to_toml
from tabletop.eval.tasks import (
    GOAL_TYPES,
    TaskFileError,
    Truth,
    list_shipped_tasks,
    load_tasks,
    parse_tasks,
)
from tabletop.eval.truth import check_absent, resolve_truth
from tabletop.sim.ground_truth import GroundTruth

DOC = {
    "format": "tabletop-tasks",
    "version": 1,
    "name": "t",
    "scene": {"name": "default"},
    "scan": {"seed": 1, "speed": 0.45, "episodes": 4},
    "goals": [
        {
            "id": "o",
            "type": "object",
            "text": "the red mug",
            "query": {"obj": "red mug"},
            "truth": {"object": "red_mug"},
        },
        {
            "id": "a",
            "type": "ambiguous",
            "text": "the mug near the dog",
            "query": {"sound": "a dog barking", "obj": "mug"},
            "primary": "obj",
            "truth": {"object": "red_mug"},
        },
        {
            "id": "s",
            "type": "spatial",
            "text": "between",
            "relation": "between",
            "landmarks": [{"obj": "tray"}, {"obj": "red mug"}],
            "truth": {"relation": "between", "of": [{"object": "tray"}, {"object": "red_mug"}]},
        },
        {
            "id": "i",
            "type": "image",
            "text": "this image",
            "query": {"img": {"eye": [0.4, 0.3, 0.4], "look_at": [0.4, 0.3, 0.0]}},
            "truth": {"camera": [0.4, 0.3, 0.4]},
        },
        {
            "id": "n",
            "type": "instruction",
            "text": "go to the red mug",
            "instruction": "go to the red mug",
            "truth": {"object": "red_mug"},
        },
    ],
    "sequences": [{"id": "q", "goals": ["s", "o"]}],
}

GT = GroundTruth.from_dict(
    ground_truth_dict(
        objects=[
            {"name": "red_mug", "aabb_min": [0.3, 0.2, 0.0], "aabb_max": [0.4, 0.3, 0.1]},
            {"name": "tray", "aabb_min": [0.5, -0.1, 0.0], "aabb_max": [0.7, 0.1, 0.02]},
        ],
        sound_events=[
            {
                "category": "dog",
                "onset_s": 5.0,
                "table_point": [0.6, 0.3, 0.0],
                "tcp_mean": [0, 0, 0.3],
            },
            {
                "category": "dog",
                "onset_s": 1.0,
                "table_point": [0.3, -0.3, 0.0],
                "tcp_mean": [0, 0, 0.3],
            },
        ],
        areas=[
            {
                "name": "left side of the table",
                "aliases": ["left"],
                "x": [0.2, 0.7],
                "y": [0.2, 0.5],
            }
        ],
    )
)


ABSENT = {
    "id": "x",
    "type": "absent",
    "text": "the giraffe",
    "query": {"obj": "giraffe"},
    "truth": {"absent": True},
}


def bad(mutate):
    d = copy.deepcopy(DOC)
    d["goals"].append(copy.deepcopy(ABSENT))
    mutate(d)
    with pytest.raises(TaskFileError) as e:
        parse_tasks(d, source="t.toml")
    return str(e.value)


def test_valid_file_parses_with_sequences_first():
    tf = parse_tasks(copy.deepcopy(DOC), source="t.toml")
    assert [g.id for g in tf.goals] == ["o", "a", "s", "i", "n"]
    amb = tf.goal("a")
    assert [k for k, _ in amb.query.parts] == ["obj", "sound"] and amb.query.primary == "obj"
    assert tf.goal("i").needs_image and not tf.goal("o").needs_image
    runs = tf.runs()
    assert runs[0] == ("q", [tf.goal("s"), tf.goal("o")])
    assert [sid for sid, _ in runs[1:]] == ["a", "i", "n"]  # the rest one by one


@pytest.mark.parametrize(
    ("mutate", "needles"),
    [
        (lambda d: d["goals"][0].update(type="objekt"), ["unknown goal type 'objekt'", "sound"]),
        (lambda d: d["goals"][0].update(colour="red"), ["unknown keys ['colour']", "query"]),
        (lambda d: d["goals"][0].pop("truth"), ["missing required keys ['truth']", "'o'"]),
        (
            lambda d: d["goals"][0].update(truth={"thing": 1}),
            ["give exactly one of", "object", "relation"],
        ),
        (lambda d: d["goals"][0]["query"].update(smell="x"), ["unknown query parts ['smell']"]),
        (
            lambda d: d["goals"][0]["query"].update(sound="dog"),
            ["'object' goal queries obj= alone", "ambiguous"],
        ),
        (lambda d: d["goals"][1].update(primary="img"), ["primary 'img' is not one of"]),
        (lambda d: d["goals"][2]["landmarks"].pop(), ["relation 'between' takes 2 landmarks"]),
        (lambda d: d["goals"][2].update(relation="near"), ["unknown relation 'near'", "left_of"]),
        (
            lambda d: d["goals"][2]["landmarks"].__setitem__(0, {"sound": "dog"}),
            ["multimodal_spatial"],
        ),
        (lambda d: d["goals"][3]["query"]["img"].pop("eye"), ["missing required keys ['eye']"]),
        (lambda d: d["goals"][3]["truth"].update(camera=[1, 2]), ["list of 3 finite numbers"]),
        (lambda d: d["goals"][1].update(id="o"), ["goal ids must be unique", "'o'"]),
        (lambda d: d["sequences"][0]["goals"].append("zz"), ["unknown goal id 'zz'"]),
        (lambda d: d["scene"].update(path="x.toml"), ["exactly one of name, path, random"]),
        (lambda d: d.update(version=9), ["version 9 is not supported"]),
        (lambda d: d.update(format="x"), ["expected 'tabletop-tasks'"]),
        (lambda d: d["scan"].update(episodes=-1), ["[scan]", "episodes"]),
        (lambda d: d["scan"].update(sped=1), ["unknown keys ['sped']", "speed"]),
        (lambda d: d.update(goals=[]), ["non-empty list"]),
        # non-finite numbers (TOML has nan and inf) and bad [noise] sections
        (
            lambda d: d["goals"][3]["truth"].update(camera=[0.4, float("nan"), 0.4]),
            ["'i'", "list of 3 finite numbers", "nan"],
        ),
        (
            lambda d: d["goals"][3]["query"]["img"].update(eye=[float("inf"), 0.3, 0.4]),
            ["img.eye", "finite numbers"],
        ),
        (lambda d: d["scan"].update(speed=float("nan")), ["[scan]", "speed must be a finite"]),
        (lambda d: d.update(noise={"pose": 0.1}), ["[noise]", "unknown settings ['pose']"]),
        (
            lambda d: d.update(noise={"drop_frames": float("inf")}),
            ["[noise]", "drop_frames must be a finite number"],
        ),
        (lambda d: d.update(noise=[1]), ["[noise] must be a table"]),
        (lambda d: d.update(name=7), ["name must be a string, got 7"]),
        # absent goals: one obj=, sound= or area= part, truth { absent = true }, nowhere else
        (
            lambda d: d["goals"][5]["query"].update(sound="a lion roaring"),
            [
                "'x'",
                "an 'absent' goal asks for one thing",
                "['obj', 'sound', 'area']",
                "got ['obj', 'sound']",
            ],
        ),
        (
            lambda d: d["goals"][5].update(
                query={"img": {"eye": [0.3, 0.0, 0.4], "look_at": [0.5, 0.0, 0.0]}}
            ),
            ["an 'absent' goal asks for one thing", "got ['img']"],
        ),
        (
            lambda d: d["goals"][5].update(truth={"object": "red_mug"}),
            ["an 'absent' goal's truth is { absent = true }, got object red_mug"],
        ),
        (lambda d: d["goals"][5].update(truth={"absent": False}), ["absent must be true"]),
        (lambda d: d["goals"][5].update(truth={"absent": "yes"}), ["absent must be true"]),
        (lambda d: d["goals"][5].update(primary="obj"), ["unknown keys ['primary']"]),
        (
            lambda d: d["goals"][0].update(truth={"absent": True}),
            ["'o'", "truth { absent = true } belongs to type 'absent' goals", "'object' goal"],
        ),
        (
            lambda d: d["goals"][2]["truth"]["of"].__setitem__(0, {"absent": True}),
            ["of[0]", "a relation's landmark cannot be absent"],
        ),
    ],
)
def test_bad_files_name_the_problem_and_the_options(mutate, needles):
    msg = bad(mutate)
    assert msg.startswith("t.toml")
    for n in needles:
        assert n in msg, (n, msg)


def test_absent_goal_parses_and_resolves_to_nowhere():
    d = copy.deepcopy(DOC)
    d["goals"] += [ABSENT, {**ABSENT, "id": "y", "query": {"sound": "a submarine"}}]
    tf = parse_tasks(d, source="t.toml")
    g = tf.goal("x")
    assert (
        g.type == "absent" and g.truth == Truth("absent") and g.query.parts == (("obj", "giraffe"),)
    )
    assert tf.goal("y").query.primary == "sound" and "absent" in GOAL_TYPES
    r = resolve_truth(g.truth, GT, "f.toml goal 'x' truth")
    assert r.boxes.shape == (0, 2, 3) and r.distance([0.35, 0.25, 0.05]) == float("inf")
    check_absent(g.query, GT, "x")  # no giraffe in GT


@pytest.mark.parametrize(
    ("part", "needle"),
    [
        (("obj", "the Red  Mug"), "(object red_mug)"),  # case, articles and spaces aside
        (("obj", "tray"), "(object tray)"),
        (("obj", "mug"), "(object red_mug)"),  # the kind
        (("sound", "a dog"), "(sound dog)"),  # the caption
        (("sound", "dog"), "(sound dog)"),  # the category
        (("area", "the left side of the table"), "(area left side of the table)"),
    ],
)
def test_an_absent_goal_naming_what_the_scene_has_is_refused(part, needle):
    from tabletop.eval.tasks import Landmark

    with pytest.raises(TaskFileError) as e:
        check_absent(Landmark((part,), part[0]), GT, "f.toml goal 'x'")
    msg = str(e.value)
    assert msg.startswith("f.toml goal 'x': an 'absent' goal asks") and needle in msg, msg


def test_load_errors_name_the_file(tmp_path):
    with pytest.raises(TaskFileError, match="does not exist; give a .toml or .json task file"):
        load_tasks(tmp_path / "nope.toml")
    with pytest.raises(TaskFileError, match="is a directory, not a file; give a .toml"):
        load_tasks(tmp_path)
    p = tmp_path / "broken.toml"
    p.write_text("format = ")
    with pytest.raises(TaskFileError, match="broken.toml is not valid TOML"):
        load_tasks(p)
    p = tmp_path / "t.yaml"
    p.write_text("x")
    with pytest.raises(TaskFileError, match="valid: .toml, .json"):
        load_tasks(p)


def test_toml_writer_round_trips(tmp_path):
    p = tmp_path / "t.toml"
    p.write_text(to_toml(DOC, "a header"))
    j = tmp_path / "t.json"
    j.write_text(json.dumps(DOC))
    a, b = load_tasks(p), load_tasks(j)
    assert a.goals == b.goals and a.sequences == b.sequences and a.scan == b.scan


def test_truth_resolves_against_ground_truth():
    r = resolve_truth(Truth("object", object="red_mug"), GT)
    assert r.distance([0.35, 0.25, 0.05]) == 0.0
    assert r.distance([0.35, 0.25, 0.2]) == pytest.approx(0.1)
    # a sound heard twice counts at either place, up to the microphone's height
    s = resolve_truth(Truth("sound", sound="dog"), GT)
    assert len(s.boxes) == 2 and s.distance([0.6, 0.3, 0.25]) == 0.0
    first = resolve_truth(Truth("sound", sound="dog", occurrence=0), GT)  # in time order
    assert first.distance([0.3, -0.3, 0.0]) == 0.0 and first.distance([0.6, 0.3, 0.0]) > 0.5
    a = resolve_truth(Truth("area", area="left"), GT)
    assert a.distance([0.5, 0.3, 0.1]) == 0.0
    left = resolve_truth(
        Truth("relation", relation="left_of", of=(Truth("object", object="red_mug"),)), GT
    )
    # 10 cm to the left (+y) of the centre, level with the top (robot API conventions)
    assert np.allclose(left.boxes[0, 0], [0.35, 0.35, 0.1])
    mid = resolve_truth(
        Truth(
            "relation",
            relation="between",
            of=(Truth("object", object="tray"), Truth("sound", sound="dog", occurrence=1)),
        ),
        GT,
    )
    assert np.allclose(mid.boxes[0, 0], [0.6, 0.15, 0.005])


@pytest.mark.parametrize(
    ("truth", "needle"),
    [
        (
            Truth("object", object="blue_mug"),
            "no object 'blue_mug' in the scene; objects: ['red_mug'",
        ),
        (Truth("sound", sound="cat"), "'cat' was not inserted in this scan; inserted: ['dog']"),
        (Truth("sound", sound="dog", occurrence=2), "occurrences 0..1"),
        (Truth("area", area="kitchen"), "no area 'kitchen'; areas: ['left side of the table']"),
        (
            Truth("relation", relation="behind", of=(Truth("sound", sound="dog"),)),
            "heard in 2 places; a relation needs one: give occurrence = 0..1",
        ),
    ],
)
def test_truth_references_the_recording_lacks_are_named(truth, needle):
    with pytest.raises(TaskFileError) as e:
        resolve_truth(truth, GT, "f.toml goal 'x' truth")
    assert needle in str(e.value) and str(e.value).startswith("f.toml goal 'x' truth")


def _g(gid, seq, success, status="done", err=0.01):
    return GoalResult(gid, "object", gid, seq, status, success=success, target_error_m=err)


def test_in_a_row_counts_leading_successes():
    seqs = [
        [_g("a", "1", True), _g("b", "1", True), _g("c", "1", False)],
        [_g("d", "2", True), _g("e", "2", False), _g("f", "2", True)],
        [_g("g", "3", False), _g("h", "3", True)],
    ]
    r = in_a_row(seqs)
    assert r["1"]["success_rate"] == pytest.approx(2 / 3)
    assert r["2"]["success_rate"] == pytest.approx(1 / 3)
    assert r["3"] == {"sequences": 2, "success_rate": 0.0}


def test_unavailable_goals_and_encoder_sets_are_reported_not_counted():
    goals = [
        _g("a", "a", True),
        _g("b", "b", False, status="not_found", err=None),
        GoalResult("c", "image", "img", "c", "unavailable", reason="image goals unavailable: x"),
    ]
    run = EncoderRun("oracle", {"set": "oracle"}, True, tasks=[TaskRun("t", "t.toml", "s", goals)])
    off = EncoderRun("default", {}, False, "ConfigError: not wired")
    res = EvalResult(["t.toml"], [run, off])
    s = res.to_json()
    assert s["encoders"] == "oracle" and "simulator upper bound" in s["encoders_label"]
    obj = s["by_type"]["object"]
    assert obj["success_rate"] == 0.5 and obj["recall_at"]["2cm"] == 0.5 and obj["not_found"] == 1
    assert s["by_type"]["image"]["success_rate"] is None
    assert s["by_type"]["image"]["unavailable"] == 1
    assert s["rows"][1]["available"] is False and "not wired" in s["rows"][1]["reason"]
    md = res.to_markdown()
    assert "unavailable: image goals unavailable: x" in md
    assert "default | unavailable: ConfigError: not wired" in md


def test_absent_goals_count_when_reported_not_found_and_have_no_recall():
    absent = [
        GoalResult("n", "absent", "the giraffe", "n", "not_found", success=True, tcp=(0.3, 0, 0.4)),
        GoalResult(
            "f",
            "absent",
            "a laptop",
            "f",
            "done",
            reason="found at [0.5, 0.1, 0.05] (a false positive)",
            target=(0.5, 0.1, 0.05),
            tcp=(0.5, 0.1, 0.09),
        ),
        GoalResult("r", "absent", "a submarine", "r", "failed", reason="ConfigError: x"),
    ]
    goals = [_g("a", "a", True), *absent]
    run = EncoderRun("oracle", {"set": "oracle"}, True, tasks=[TaskRun("t", "t.toml", "s", goals)])
    res = EvalResult(["t.toml"], [run])
    s = res.to_json()
    ab = s["by_type"]["absent"]
    assert list(s["by_type"]) == ["object", "absent"]  # GOAL_TYPES order
    assert ab["goals"] == 3 and ab["success_rate"] == pytest.approx(1 / 3) and ab["not_found"] == 1
    assert set(ab["recall_at"].values()) == {None} and ab["mean_target_error_m"] is None
    # "all": success over every goal, recall over the goals with a place
    assert s["all"]["success_rate"] == 0.5 and s["all"]["recall_at"]["2cm"] == 1.0
    md = res.to_markdown()
    assert "| absent | oracle (simulator upper bound) | 3 | 33 (1/3) | – | – | – |" in md
    assert "success: not found" in md and "miss: found at [0.5, 0.1, 0.05] (a false positive)" in md


def test_shipped_suites_cover_every_goal_type():
    from tabletop.eval.runner import collect_task_files

    files = collect_task_files("default")
    scenes = {json.dumps(f.scene.__dict__, default=str, sort_keys=True) for f in files}
    goals = [g for f in files for g in f.goals]
    assert len(scenes) >= 5 and len(goals) >= 150
    # absent goals are the paraphrase suites' (tests/test_paraphrase.py)
    assert {g.type for g in goals} == set(GOAL_TYPES) - {"absent"}
    assert sum(len(f.sequences) for f in files) >= 5
    assert "demo" in list_shipped_tasks()
    demo = load_tasks("demo")
    assert {g.type for g in demo.goals} == set(GOAL_TYPES) - {"absent"}
    assert len(demo.goals) <= 30


def test_shipped_clutter_suites_are_dense_tables_with_goals_on_beside_and_between():
    from tabletop.eval.paraphrase import HELDOUT_SEEDS, TUNE_SEEDS
    from tabletop.eval.runner import collect_task_files
    from tabletop.eval.suites import CLUTTER_SEEDS, DEFAULT_SUITES
    from tabletop.sim.generator import TALL_KINDS

    files = collect_task_files("clutter")
    assert [f.scene.random["seed"] for f in files] == list(CLUTTER_SEEDS)
    used = {s["random"]["seed"] for _, s, _ in DEFAULT_SUITES if "random" in s}
    used |= {*TUNE_SEEDS, *HELDOUT_SEEDS, *range(700, 706), 900, 901, 902}
    assert not used & set(CLUTTER_SEEDS)
    for f in files:
        spec = f.scene.load()
        kinds = [o.kind for o in spec.objects]
        assert f.scene.random["profile"] == "clutter" and len(kinds) >= 10
        assert sum(kinds.count(k) == 2 for k in set(kinds)) >= 3
        assert any(k in TALL_KINDS for k in kinds)
        relations = {g.relation for g in f.goals if g.type == "spatial"}
        assert {g.type for g in f.goals} == {"object", "spatial"}
        assert "between" in relations and len(relations) >= 3, (f.name, relations)
    assert sum(len(f.goals) for f in files) >= 100


def test_reach_summary_counts_right_targets_routes_and_audited_blocks():
    def g(gid, success, terr, route, reach="reached", audit="", plan=None):
        return GoalResult(
            gid, "object", gid, gid, "done", success=success, target_error_m=terr,
            route=route, reach=reach, audit=audit, planning_s=plan,
        )  # fmt: skip

    goals = [
        g("a", True, 0.01, "local"),
        g("b", False, 0.02, "none", "blocked", "feasible"),
        g("c", False, 0.30, "none", "blocked", "infeasible"),  # wrong target: not counted
        g("d", True, 0.05, "planned", plan=0.2),
    ]
    x = EvalResult(["t"], [EncoderRun("oracle", {}, True, tasks=[TaskRun("t", "t", "s", goals)])])
    r = x.to_json()["reach"]
    assert (r["right_target"], r["right_target_successes"]) == (3, 2)
    assert r["routes"] == {"none": 2, "local": 1, "planned": 1} and r["fallback_share"] == 0.5
    assert r["planning_ms_median"] == pytest.approx(200.0)
    assert (r["blocked"], r["blocked_audit_feasible"]) == (2, 1)
    assert "67 (2/3)" in x.reach_markdown() and "found a collision-free" in x.reach_markdown()


def test_every_relation_is_a_target_primitive_of_the_robot_api():
    from tabletop.eval.tasks import RELATIONS
    from tabletop.robot.primitives import primitive

    for relation, n in RELATIONS.items():
        p = primitive(relation)  # the runner calls robot.<relation>(*landmarks)
        assert p.kind == "target" and len(p.params) == n


def test_results_json_is_strict_json_without_nan():
    from tabletop.eval.results import dumps

    goals = [_g("a", "a", True, err=float("nan"))]
    run = EncoderRun("oracle", {"set": "oracle"}, True, tasks=[TaskRun("t", "t.toml", "s", goals)])
    text = dumps(EvalResult(["t.toml"], [run]).to_json() | {"x": np.float32("inf")})
    assert "NaN" not in text and "Infinity" not in text

    def refuse(word):
        raise ValueError(f"non-strict JSON constant {word}")

    d = json.loads(text, parse_constant=refuse)
    assert d["x"] is None


def test_robustness_drops_are_points_below_clean_per_goal_type():
    from tabletop.eval.robustness import RobustnessResult

    def result(successes):
        goals = [
            GoalResult(f"g{i}", t, "x", f"g{i}", "done", success=ok, target_error_m=0.01)
            for i, (t, ok) in enumerate(successes)
        ]
        run = EncoderRun("default", {"set": "default"}, True)
        run.tasks = [TaskRun("t", "t.toml", "s", goals)]
        return EvalResult(["t.toml"], [run])

    clean = [("object", True)] * 4 + [("sound", True), ("sound", False)]
    pose = [("object", True)] * 3 + [("object", False), ("sound", True), ("sound", False)]
    res = RobustnessResult(
        {"clean": result(clean), "pose": result(pose)}, {"pose": {"pose_translation_m": 0.005}}
    )
    d = res.drops["default"]["pose"]
    assert d["object"]["drop_points"] == pytest.approx(25.0)
    assert d["sound"]["drop_points"] == pytest.approx(0.0)
    assert d["all"]["drop_points"] == pytest.approx(100 * (5 / 6 - 4 / 6))
    assert res.worst_drop == pytest.approx(25.0)
    md = res.to_markdown()
    assert "| object | 100 (4/4) | 75 (-25) |" in md
    assert "pose_translation 5 mm" in md and "default" in md
