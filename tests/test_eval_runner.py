"""End to end on a short scan of the default scene with the oracle encoders: a task file is
generated from the scan's ground truth, written, run through the robot API on SimArm, scored,
reported; a second run reuses the cached recording and map."""

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from tabletop.errors import ConfigError, GoalNotFound
from tabletop.eval import load_tasks, run_eval
from tabletop.eval.runner import collect_task_files, scan_recording
from tabletop.eval.suites import generate_suite, to_toml
from tabletop.eval.tasks import TaskFileError
from tabletop.sim.ground_truth import GroundTruth

SCENE = {"name": "default"}
SCAN = {"seed": 1, "speed": 0.6, "episodes": 3, "episode_s": 2.0, "repeat_sounds": 0}
COUNTS = dict(
    object=3, sound=1, image=1, area=0, amb_sound=1, amb_image=0, amb_object=0, amb_area=0,
    spatial=1, mm_spatial=0, instruction=1, sequences=1,
)  # fmt: skip


ABSENT = {
    "id": "absent-giraffe",
    "type": "absent",
    "text": "the giraffe",
    "query": {"obj": "the giraffe"},
    "truth": {"absent": True},
}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("eval")
    cache = tmp / "cache"
    rec, cached = scan_recording(SCENE, SCAN, cache)
    assert not cached
    doc = generate_suite("tiny", SCENE, SCAN, GroundTruth.of(rec), COUNTS, seed=3,
                         map_section={"frame_step": 4})  # fmt: skip
    doc["goals"].append(dict(ABSENT))
    path = tmp / "tiny.toml"
    path.write_text(to_toml(doc))
    out = tmp / "report"
    result = run_eval(path, encoders="oracle", out_dir=out, progress=False, cache_dir=cache)
    return path, cache, out, result


def test_goals_succeed_and_json_has_the_summary(run):
    path, _, _, result = run
    tf = load_tasks(path)
    d = result.to_json()
    assert d["encoders"] == "oracle" and d["encoders_label"].endswith("(simulator upper bound)")
    assert d["encoder_names"]["set"].startswith("oracle")
    assert d["contacts"] == 0
    by = d["by_type"]
    assert {"object", "sound", "image", "ambiguous", "spatial", "instruction"} <= set(by)
    for t in ("object", "ambiguous", "spatial"):
        assert by[t]["success_rate"] == 1.0, (t, by[t])
        assert by[t]["recall_at"]["10cm"] == 1.0
        assert by[t]["mean_error_m"] <= 0.10 and by[t]["time_per_goal_s"] > 0
    assert by["object"]["recall_at"]["2cm"] == 1.0  # the oracle map puts objects on their boxes
    assert by["sound"]["success_rate"] == 1.0
    # the oracle map has no giraffe: reported not found, and the arm did not move for it
    ab = by["absent"]
    assert ab["success_rate"] == 1.0 and ab["not_found"] == 1 and ab["recall_at"]["2cm"] is None
    (g,) = [g for t in d["rows"][0]["tasks"] for g in t["goals"] if g["type"] == "absent"]
    assert g["status"] == "not_found" and g["target"] is None and "giraffe" in g["reason"]
    assert by["instruction"]["attempted"] == 1  # through the instruction parser
    img = [g for t in d["rows"][0]["tasks"] for g in t["goals"] if g["type"] == "image"]
    assert img and all(
        g["status"] == "done" or "image goals unavailable" in g["reason"] for g in img
    )
    # a sequence of four (sound, image, object, object) like the paper's tables
    assert len(tf.sequences) == 1 and len(tf.sequences[0][1]) == 4
    assert set(d["in_a_row"]) >= {"1", "2", "3"}
    assert d["in_a_row"]["1"]["sequences"] == 1
    assert d["all"]["goals"] == len(tf.goals)


def test_each_task_names_its_cached_map_and_recording_for_the_viewer(run):
    from tabletop.viewer.session import ViewerSession

    _, cache, out, result = run
    (t,) = result.to_json()["rows"][0]["tasks"]
    assert Path(t["map_file"]).is_file() and Path(t["map_file"]).parent == cache
    assert (Path(t["recording_dir"]) / "recording.json").is_file()
    # `tabletop view MAP --eval OUT` steps through the goals that ran on that map
    goals = ViewerSession(t["map_file"], eval_dir=out).eval_goals()
    assert len(goals) == len(t["goals"]) and all(g.same_map for g in goals)


def test_report_is_written_and_references_its_pictures(run):
    _, _, out, result = run
    report = out / "report.md"
    assert result.report_path == report and report.is_file()
    text = report.read_text()
    assert "simulator upper bound" in text and "| object | oracle" in text
    figs = result.runs[0].tasks[0].figures
    assert "scene" in figs and any(k.startswith("heatmaps:") for k in figs)
    for rel in figs.values():
        assert f"]({rel})" in text and (out / rel).is_file() and (out / rel).stat().st_size > 1000
    saved = json.loads((out / "results.json").read_text())
    assert saved["by_type"]["object"]["success_rate"] == 1.0


def test_cli_json_second_run_reuses_the_cached_scan_and_map(run, capfd, tmp_path):
    from tabletop.cli import main

    path, cache, _, first = run
    capfd.readouterr()
    argv = ["eval", str(path), "--json", "--goals", "--cache-dir", str(cache)]
    assert main([*argv, "--out", str(tmp_path / "again")]) == 0
    out = capfd.readouterr().out
    d = json.loads(out)  # nothing but the JSON on stdout
    assert d["encoders"] == "oracle" and "by_type" in d and d["contacts"] == 0
    task = d["rows"][0]["tasks"][0]
    assert task["cached"] and task["scan_s"] == 0.0 and task["map_s"] == 0.0
    a = [(g.goal_id, g.success) for g in first.runs[0].goals]
    assert a == [(g["goal_id"], g["success"]) for g in task["goals"]]


def test_a_cached_map_is_judged_by_the_committed_calibration_and_todays_descriptions(run):
    from tabletop.eval.harness import catalog_descriptions, scene_map
    from tabletop.eval.tasks import scene_ref
    from tabletop.mapping import AVLMap, load_calibration
    from tabletop.mapping.calibration import Calibration

    _, cache, _, _ = run
    (path,) = cache.glob("map-oracle-*.npz")
    m = AVLMap.load(path)
    committed = load_calibration("oracle")
    assert committed.thresholds  # so that a calibration without any differs from it
    m.calibration = Calibration("oracle", {}, {})  # as a map saved before a recalibration
    m.set_descriptions({"mug": ("an old description",)})  # ... and before new descriptions
    m.save(path)
    spec = scene_ref(SCENE).load()
    _, again = scene_map(spec, SCAN, "oracle", map_settings={"frame_step": 4}, cache_dir=cache)
    assert again.calibration.thresholds == committed.thresholds
    assert again.calibration.models == committed.models
    today = catalog_descriptions()["mug"]
    assert again.objects.descriptions["mug"] == today == again.config.descriptions["mug"]
    assert list(cache.glob("map-oracle-*.npz")) == [path]  # the same file, not a new map


def test_query_time_modules_do_not_invalidate_cached_maps(tmp_path, monkeypatch):
    import tabletop.paths
    from tabletop.eval.harness import QUERY_TIME_SOURCES, _fingerprint

    real = tabletop.paths.PACKAGE_DIR
    assert all((real / f).is_file() for f in QUERY_TIME_SOURCES)  # no stale entry
    (tmp_path / "mapping").mkdir()
    for f in ("mapping/object_module.py", "mapping/voxel_map.py"):
        (tmp_path / f).write_text("x = 1\n")
    monkeypatch.setattr(tabletop.paths, "PACKAGE_DIR", tmp_path)
    before = _fingerprint("mapping")
    (tmp_path / "mapping/object_module.py").write_text("x = 2\n")
    assert _fingerprint("mapping") == before  # answers queries only
    (tmp_path / "mapping/voxel_map.py").write_text("x = 2\n")
    assert _fingerprint("mapping") != before  # builds maps


def test_bad_inputs_to_the_runner():
    with pytest.raises(TaskFileError, match="shipped suites"):
        collect_task_files("no-such-suite")
    with pytest.raises(Exception, match="unknown encoder set 'clip'; valid"):
        run_eval("demo", encoders="clip", progress=False, cache_dir=None)


def test_a_bad_map_value_fails_before_the_scan(tmp_path):
    from tabletop.eval.runner import evaluate_task_file

    text = load_tasks("demo").path.read_text()
    assert "[map]\nframe_step = 2" in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("[map]\nframe_step = 2", "[map]\nframe_step = 0"))
    cache = tmp_path / "cache"
    with pytest.raises(TaskFileError, match=r"\[map\].*frame_step"):
        evaluate_task_file(load_tasks(bad), "oracle", cache_dir=cache)
    assert not cache.exists() or not any(cache.iterdir())  # nothing was scanned


class _Robot:
    """The robot API as an absent goal meets it: a query, a target, a motion."""

    def __init__(self, target=None):
        self.target = target  # None: the map finds nothing
        self.moves = []
        self.contacts = []
        self.last_heatmaps = ()

    def get_major_map(self, **parts):
        return SimpleNamespace(parts=parts)

    def get_max_pos_3d(self, heat):
        if self.target is None:
            raise GoalNotFound("obj='the giraffe'", "below the calibrated threshold")
        return np.array(self.target)

    def move_to(self, target):
        self.moves.append(np.asarray(target))
        self.contacts.append(0)
        return SimpleNamespace(
            final_tcp=np.asarray(target) + np.array([0.0, 0.0, 0.04]),
            reached=True,
            reason=SimpleNamespace(value="reached"),
        )

    def current_position(self):
        return np.array([0.3, 0.0, 0.5]) if not self.moves else self.moves[-1]


@pytest.mark.parametrize("target", [None, (0.5, 0.1, 0.05)])
def test_an_absent_goal_succeeds_only_when_nothing_is_found(target):
    from tabletop.eval.runner import _run_goal
    from tabletop.eval.tasks import parse_tasks
    from tabletop.eval.truth import resolve_truth

    tf = parse_tasks(
        {"format": "tabletop-tasks", "version": 1, "scene": SCENE, "goals": [ABSENT]}, "t.toml"
    )
    goal = tf.goals[0]
    robot = _Robot(target)
    ctx = SimpleNamespace(robot=robot, keep_heatmaps=set(), heatmaps={}, images={})
    r = _run_goal(ctx, goal, "s", resolve_truth(goal.truth, None))
    if target is None:  # not found: a success, and nothing moved
        assert r.success and r.status == "not_found" and not robot.moves
        assert "below the calibrated threshold" in r.reason and r.target is None
    else:  # a false positive: the robot went there, the goal failed with its target
        assert not r.success and r.status == "done" and len(robot.moves) == 1
        assert r.target == target and "false positive" in r.reason and r.reach == "reached"
        assert r.error_m is None and r.target_error_m is None


def test_an_instruction_the_reader_refuses_is_a_miss_not_a_skip():
    from tabletop.eval.results import _rate
    from tabletop.eval.runner import _run_goal
    from tabletop.eval.tasks import parse_tasks
    from tabletop.eval.truth import resolve_truth
    from tabletop.reader.reading import DEFAULT_READER

    goal = {
        "id": "instruction-0",
        "type": "instruction",
        "text": "xqzt vlorp",
        "instruction": "xqzt vlorp",
        "truth": {"point": [0.5, 0.0, 0.05]},
    }
    tf = parse_tasks(
        {"format": "tabletop-tasks", "version": 1, "scene": SCENE, "goals": [goal]}, "t.toml"
    )
    robot = _Robot()
    robot.history = []
    ctx = SimpleNamespace(
        robot=robot, keep_heatmaps=set(), heatmaps={}, images={}, radius=0.10,
        distance=lambda region, p: region.distance(p), reader=DEFAULT_READER,
    )  # fmt: skip
    r = _run_goal(ctx, tf.goals[0], "s", resolve_truth(tf.goals[0].truth, None))
    assert r.status == "failed" and not r.success and not robot.moves
    assert r.reason.startswith("ParseError: ")
    rate = _rate([r])
    assert rate["attempted"] == 1 and rate["success_rate"] == 0.0 and rate["unavailable"] == 0


@pytest.mark.parametrize("target", [None, (0.5, 0.1, 0.05)])
def test_an_absent_place_succeeds_only_when_nothing_is_found(target):
    from tabletop.eval.runner import _run_goal
    from tabletop.eval.tasks import parse_tasks
    from tabletop.eval.truth import resolve_truth

    place = {
        "id": "absent-area-0",
        "type": "absent",
        "text": "the garden shed",
        "query": {"area": "the garden shed"},
        "truth": {"absent": True},
    }
    tf = parse_tasks(
        {"format": "tabletop-tasks", "version": 1, "scene": SCENE, "goals": [place]}, "t.toml"
    )
    robot = _Robot(target)
    ctx = SimpleNamespace(robot=robot, keep_heatmaps=set(), heatmaps={}, images={})
    r = _run_goal(ctx, tf.goals[0], "s", resolve_truth(tf.goals[0].truth, None))
    assert r.success == (target is None) and len(robot.moves) == (target is not None)


def test_an_absent_goal_naming_a_scene_object_is_refused_before_anything_moves(run, tmp_path):
    from tabletop.eval.runner import evaluate_task_file

    path, cache, _, _ = run
    tf = load_tasks(path)
    label = GroundTruth.of(scan_recording(SCENE, SCAN, cache)[0]).objects[0].label
    text = path.read_text() + (
        f'\n[[goals]]\nid = "not-absent"\ntype = "absent"\ntext = "x"\n'
        f'query = {{ obj = "the {label}" }}\ntruth = {{ absent = true }}\n'
    )
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    assert len(load_tasks(bad).goals) == len(tf.goals) + 1
    with pytest.raises(TaskFileError, match="'not-absent': an 'absent' goal asks obj="):
        evaluate_task_file(load_tasks(bad), "oracle", cache_dir=cache)


def test_eval_map_refuses_zero_seeds():
    from tabletop.eval.map_goals import run_map_eval

    with pytest.raises(ConfigError, match="seeds must be a whole number >= 1"):
        run_map_eval(0)


@pytest.mark.slow  # a robustness sweep end to end (37 s): scripts/test -m slow
def test_noise_is_applied_to_the_cached_clean_scan_and_its_map_is_kept_apart(run, tmp_path):
    from tabletop.eval.robustness import run_robustness

    path, cache, _, first = run
    recs = sorted(p.name for p in cache.glob("rec-*"))
    maps = sorted(p.name for p in cache.glob("map-*"))
    res = run_robustness(
        path, encoders="oracle", out_dir=tmp_path / "rob", cache_dir=cache,
        conditions=["extrinsic"],
    )  # fmt: skip
    assert sorted(p.name for p in cache.glob("rec-*")) == recs  # no new scan
    new = sorted(set(p.name for p in cache.glob("map-*")) - set(maps))
    assert len(new) == 1  # the clean map was reused, the noisy one is its own
    clean = res.results["clean"].runs[0]
    noisy = res.results["extrinsic"].runs[0]
    assert clean.tasks[0].noise == {} and clean.tasks[0].cached
    assert noisy.tasks[0].noise["extrinsic_translation_m"] == 0.005 and not noisy.tasks[0].cached
    assert [g.success for g in clean.goals] == [g.success for g in first.runs[0].goals]
    drops = res.drops["oracle"]["extrinsic"]
    assert set(drops) >= {"object", "all"} and res.contacts == 0
    # a 5 mm / 1 degree extrinsic error moves the oracle's targets, but only by millimetres
    errs = [
        (a.target_error_m, b.target_error_m)
        for a, b in zip(clean.goals, noisy.goals, strict=True)
        if a.target_error_m is not None and b.target_error_m is not None
    ]
    assert errs and any(abs(a - b) > 1e-4 for a, b in errs)
    assert all(abs(a - b) < 0.03 for a, b in errs)
    md = (tmp_path / "rob" / "robustness.md").read_text()
    assert "`extrinsic`: extrinsic_translation 5 mm, extrinsic_rotation 1.0°" in md
    assert (tmp_path / "rob" / "extrinsic" / "report.md").is_file()


@pytest.mark.parametrize(
    "flags, needle",
    [
        (["--noise", "pose=0.1"], "--noise: unknown settings ['pose']"),
        (["--noise", "drop_frames=nan"], "drop_frames must be a finite number"),
        (["--noise", "drop_frames=1"], "drop_frames must be in [0, 1)"),
        (["--robustness", "fog"], "unknown conditions ['fog']; valid: all, or some of"),
        (["--robustness", "--noise", "drop_frames=0.1"], "exclude each other"),
    ],
)
def test_bad_noise_flags_fail_before_any_scan(flags, needle, capfd, tmp_path):
    from tabletop.cli import main

    cache = tmp_path / "cache"
    assert main(["eval", "demo", "--cache-dir", str(cache), *flags]) == 2
    assert needle in capfd.readouterr().err
    assert not cache.exists()
