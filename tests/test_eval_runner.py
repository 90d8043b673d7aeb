"""End to end on a short scan of the default scene with the oracle encoders: a task file is
generated from the scan's ground truth, written, run through the robot API on SimArm, scored,
reported; a second run reuses the cached recording and map."""

import json

import pytest

from tabletop.errors import ConfigError
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


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("eval")
    cache = tmp / "cache"
    rec, cached = scan_recording(SCENE, SCAN, cache)
    assert not cached
    doc = generate_suite("tiny", SCENE, SCAN, GroundTruth.of(rec), COUNTS, seed=3,
                         map_section={"frame_step": 4})  # fmt: skip
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


def test_eval_map_refuses_zero_seeds():
    from tabletop.eval.map_goals import run_map_eval

    with pytest.raises(ConfigError, match="seeds must be a whole number >= 1"):
        run_map_eval(0)
