"""Bad inputs an outside probe found still reaching a traceback or a silent answer: each now
gets a clear error or an honest "not found" (docs/hardening.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tabletop.atomic import check_writable
from tabletop.errors import ConfigError, RecordingError, SceneError
from tabletop.mapping import AVLMap
from tabletop.mapping.errors import MapFormatError
from tabletop.reader.llm_client import LLMConfig
from tabletop.recording import load_recording
from tabletop.sim.scene import load_scene_spec


@pytest.fixture(scope="module")
def oracle_map():
    from test_hardening_honest import small_recording

    from tabletop.eval.harness import build_map, map_config

    return build_map(small_recording(2), "oracle", map_config(visual=None))


def test_a_path_longer_than_the_system_takes_is_named(tmp_path):
    deep = tmp_path.joinpath(*["d" * 200] * 25, "m.npz")
    with pytest.raises(ConfigError, match="is longer than the system's 4096 bytes"):
        check_writable(deep)


def test_scene_specs_that_are_not_text_or_not_a_table_are_named(tmp_path):
    garbage, null = tmp_path / "garbage.toml", tmp_path / "null.json"
    garbage.write_bytes(b"\xda\xff\x00garbage")
    null.write_text("null")
    with pytest.raises(SceneError, match=r"is not text \(not UTF-8\)"):
        load_scene_spec(garbage)
    with pytest.raises(SceneError, match="holds a NoneType, not a table of a scene's fields"):
        load_scene_spec(null)
    for bad in (None, 5):
        with pytest.raises(SceneError, match="must be a file path or a shipped scene's name"):
            load_scene_spec(bad)


def test_a_recording_path_or_option_of_the_wrong_type_is_named(tmp_path):
    for bad in (None, 5, [1], b"/tmp"):
        with pytest.raises(RecordingError, match="a recording is a directory path, got"):
            load_recording(bad)
    for workers in ("2", 0, True):
        with pytest.raises(RecordingError, match="workers must be a whole number >= 1"):
            load_recording(tmp_path, workers=workers)


def test_a_map_path_of_the_wrong_type_or_a_single_array_is_named(tmp_path):
    np.save(tmp_path / "m.npy", np.zeros(3))
    with pytest.raises(MapFormatError, match="is not a map file: a map is a .npz archive"):
        AVLMap.load(tmp_path / "m.npy")
    with pytest.raises(MapFormatError, match="a map file is a path, got NoneType"):
        AVLMap.load(None)


def test_a_map_whose_header_member_is_not_an_array_is_named(tmp_path):
    import zipfile

    from tabletop.mapping.persistence import read_map_preview

    p = tmp_path / "junk.npz"
    with zipfile.ZipFile(p, "w") as z:  # numpy hands back a non-.npy member as raw bytes
        z.writestr("header.npy", b"not an array at all")
        z.writestr("voxel_linear.npy", b"nor this")
    for read in (AVLMap.load, read_map_preview):
        with pytest.raises(MapFormatError, match="junk.npz"):
            read(p)


@pytest.mark.parametrize(
    ("url", "why"),
    [
        ("http://exa mple.com/v1", "holds a space or a control character"),
        ("http://127.0.0.1:1/v1\r\nX-Injected: 1", "holds a space or a control character"),
        ("http://[::1/v1", "is not a URL"),
    ],
)
def test_an_llm_url_with_spaces_controls_or_a_broken_host_is_named(url, why):
    with pytest.raises(ConfigError, match=why):
        LLMConfig(base_url=url, model="m")


def test_an_llm_timeout_no_clock_can_wait_is_named():
    with pytest.raises(ConfigError, match=r"timeout_s must be in \(0, 86400\] s"):
        LLMConfig(base_url="http://127.0.0.1:8000/v1", model="m", timeout_s=1e308)


@pytest.mark.parametrize("query", ["the", "it", "a the"])
def test_a_query_of_words_that_name_nothing_is_not_found(oracle_map, query):
    for which in ("object", "sound"):
        h = getattr(oracle_map, f"{which}_heatmap")(query)
        assert not h.found and not h.values.any()
        assert h.reason == f"{query!r} holds no word that names a thing, a sound or a place"


def test_a_script_the_english_text_encoder_cannot_read_is_not_found(oracle_map):
    h = oracle_map.object_heatmap("كوب")
    assert not h.found and "cannot read" in h.reason
    # full-width Latin letters are letters: read as the plain word
    wide, plain = oracle_map.object_heatmap("ｒｅｄ ｍｕｇ"), oracle_map.object_heatmap("red mug")
    assert wide.found and np.array_equal(wide.values, plain.values)


@pytest.mark.parametrize("query", ["\x1b[31mred mug\x1b[0m", "mug\r\nduck", "red\tmug"])
def test_a_query_with_control_characters_is_refused_by_name(oracle_map, query):
    with pytest.raises(ConfigError, match="holds a control character"):
        oracle_map.object_heatmap(query)


def test_nothing_here_reads_a_path_it_was_not_given():
    assert not Path("m.npz").exists()  # the checks above wrote nothing in the working directory


def test_a_robot_without_a_map_or_given_something_else_is_named(oracle_map):
    from tabletop.robot import MobileBase

    with pytest.raises(ConfigError, match="MobileBase needs a map: an AVLMap"):
        MobileBase(None)
    with pytest.raises(ConfigError, match="MobileBase needs an AVLMap .*, got str"):
        MobileBase("map.npz")
    with pytest.raises(ConfigError, match="start must be a finite .* point .*, got 'here'"):
        MobileBase(oracle_map, start="here")


def test_a_table_map_is_refused_for_the_room_base(oracle_map, tmp_path, capsys):
    from tabletop.cli import main

    path = oracle_map.save(tmp_path / "table.npz")
    code = main(["run", str(path), "go to the mug", "--embodiment", "room", "--dry-run"])
    err = capsys.readouterr().err
    assert code == 2 and "was built in no room" in err and "--other-scene" in err
    code = main(["run", str(path), "go to the mug", "--embodiment", "room", "--room", "nowhere"])
    assert code == 2 and "no shipped room 'nowhere'" in capsys.readouterr().err


def test_a_room_given_to_a_robot_without_one_is_refused(oracle_map, tmp_path, capsys):
    from tabletop.cli import main

    # --room was ignored by every embodiment but the room's base (and by --suite)
    path = oracle_map.save(tmp_path / "table.npz")
    for extra in (["--embodiment", "point"], ["--dry-run"], ["--embodiment", "base"]):
        code = main(["run", str(path), "go to the mug", "--room", "kitchen", *extra])
        err = capsys.readouterr().err
        assert code == 2, extra
        assert "--room 'kitchen' names the room of the wheeled base" in err
        assert "give --room with --embodiment room only" in err
    code = main(["run", str(path), "--suite", "--room", "kitchen"])
    assert code == 2 and "--suite has no room" in capsys.readouterr().err
    # the point robot without --room runs as before
    assert main(["run", str(path), "go to the red mug", "--embodiment", "point"]) in (0, 1)
    assert "--room" not in capsys.readouterr().err


@pytest.mark.parametrize(
    ("field", "value"), [("max_steps", "many"), ("max_loop", 2.5), ("max_calls", True)]
)
def test_a_sandbox_limit_that_is_not_a_whole_number_is_named(field, value):
    from tabletop.language.sandbox import SandboxConfig

    with pytest.raises(ConfigError, match=f"SandboxConfig.{field} must be a whole number >= 1"):
        SandboxConfig(**{field: value})
    for t in ("soon", float("inf"), float("nan")):
        with pytest.raises(ConfigError, match="timeout_s must be a finite number > 0"):
            SandboxConfig(timeout_s=t)


def test_the_viewer_names_a_bad_scene_or_reader_before_serving(capsys, tmp_path):
    pytest.importorskip("viser", reason="the viewer extra is not installed")
    from tabletop.cli import main

    missing = str(tmp_path / "none.npz")  # the flags are checked before the map is read
    assert main(["view", missing, "--scene", "nowhere"]) == 2
    assert "no shipped scene 'nowhere'; shipped: ['default'" in capsys.readouterr().err
    assert main(["view", missing, "--reader", "psychic"]) == 2
    err = capsys.readouterr().err
    assert "--reader 'psychic': valid rules+learned, learned" in err


@pytest.mark.parametrize(("out", "why"), [("", "is empty"), ("DIR/", "is a directory")])
def test_a_query_picture_prefix_that_names_no_file_is_refused(tmp_path, capsys, out, why):
    from tabletop.cli import main

    out = out.replace("DIR", str(tmp_path))
    code = main(["query", str(tmp_path / "none.npz"), "--obj", "mug", "--out", out])
    err = capsys.readouterr().err
    assert code == 2 and f"--out {out!r} {why}" in err and "_top.png and " in err
    assert list(tmp_path.iterdir()) == []  # refused before the map is read; nothing written


def test_the_pictures_of_a_prefix_are_next_to_it_and_an_existing_directory_is_no_prefix(
    tmp_path,
):
    from tabletop.mapping.render import heatmap_view_paths

    assert heatmap_view_paths(tmp_path / "q") == [tmp_path / "q_top.png", tmp_path / "q_side.png"]
    with pytest.raises(ConfigError, match="is a directory: a prefix ends in the name"):
        heatmap_view_paths(tmp_path)


def test_an_arm_reset_names_a_bad_configuration_and_refuses_after_close(oracle_map):
    from tabletop.robot.api import PrimitiveArgumentError, RobotClosed
    from tabletop.robot.arm import SimArm

    arm = SimArm(oracle_map, "default")
    q0 = arm.world.arm_q()
    for bad in ("home", [0.0] * 6, [float("nan")] * 7, [10.0] * 7, [True] * 7):
        with pytest.raises(PrimitiveArgumentError, match=r"reset\(q=...\): q must be 7 finite"):
            arm.reset(q=bad)
    np.testing.assert_array_equal(arm.world.arm_q(), q0)  # nothing moved
    arm.reset(q0 + 0.1)
    np.testing.assert_allclose(arm.world.arm_q(), q0 + 0.1)
    arm.close()
    with pytest.raises(RobotClosed, match="reset: this SimArm was closed"):
        arm.reset()


@pytest.mark.parametrize(
    ("name", "text"), [("e.toml", ""), ("c.toml", "# a comment\n"), ("e.json", "{}")]
)
def test_an_empty_scene_or_room_file_is_no_scene(tmp_path, name, text):
    from tabletop.sim.room import load_room_spec

    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(SceneError, match=r"scene spec .* is empty \(no fields\).*\['default'"):
        load_scene_spec(path)
    with pytest.raises(SceneError, match=r"room spec .* is empty \(no fields\)"):
        load_room_spec(path)


def test_a_base_sent_under_the_table_is_not_reported_as_reached(oracle_map):
    from tabletop.robot import MobileBase

    base = MobileBase(oracle_map)
    start = base.current_position()
    r = base.move_to([0.4, 0.0, -0.5])
    assert not r.reached and r.reason == "below_table" and len(r.path) == 0
    assert "0.50 m below the table's top" in r.note and "nothing moved" in r.note
    np.testing.assert_array_equal(base.current_position(), start)
    r = base.move_to([0.4, 0.0, -0.05])  # within the success radius of the top: driven to
    assert r.reached and r.note == "" and r.error_m <= 0.10 and r.final_position[2] == 0.0


def test_a_dry_run_refuses_a_target_off_the_map(oracle_map):
    from tabletop.language.run import TracingRobot
    from tabletop.language.suite import PointRobot

    t = TracingRobot(PointRobot(oracle_map), execute=False, start=(0.3, 0.0, 0.1))
    for call, arg in (("move_to", [1e9, 0.0, 0.0]), ("move_to", [0.3, 0.0, -0.5])):
        with pytest.raises(ConfigError, match=r"move_to: the target .* lies outside the map"):
            getattr(t, call)(arg)
    with pytest.raises(ConfigError, match=r"move_north: .* outside the map \(x -0.2 .. 0.8"):
        t.move_north(1e6)
    assert t.motions == []  # nothing recorded
    t.move_to([0.79, -0.59, -0.05])  # the map's corner, a little under the table's top
    t.move_south(0.5)
    np.testing.assert_allclose(t.targets, [[0.79, -0.59, -0.05], [0.29, -0.59, -0.05]])


def test_a_heatmap_the_same_everywhere_names_no_place(oracle_map):
    from tabletop.errors import GoalNotFound
    from tabletop.language.suite import PointRobot
    from tabletop.mapping.heatmaps import Heatmap

    grid, robot = oracle_map.grid, PointRobot(oracle_map)
    flat = Heatmap(grid, np.full(grid.shape, 0.5, np.float32), "flat", "object", 10.0, 0.9, True)
    for ask in (robot.get_max_pos_3d, robot.left_of, oracle_map.get_max_pos_3d):
        with pytest.raises(GoalNotFound, match="0.5 everywhere: it singles out no place"):
            ask(flat)
    values = np.full(grid.shape, 0.5, np.float32)
    values[30, 60, 10] = 0.6  # one voxel stands out: it is the target
    peak = flat.with_values(values)
    np.testing.assert_allclose(robot.get_max_pos_3d(peak), grid.centers([30, 60, 10]))


@pytest.mark.parametrize(
    ("text", "robot", "needle"),
    [
        ("go to the mug 21 times", "arm", "repeat a step 1 to 20 times"),
        ("please go to the mug 0 times", "arm", "repeat a step 1 to 20 times"),
        ("move -5 cm north", "arm", "more than 0 and at most 1.0 m"),
        ("move 3 m west", "arm", "more than 0 and at most 1.0 m"),
        ("turn 400 degrees left", "mobile", "at most 360 degrees"),
    ],
)
@pytest.mark.parametrize("reader", ["rules", "rules+spelling", "rules+learned"])
def test_a_number_beyond_the_robots_range_is_named_by_every_reader(text, robot, needle, reader):
    from tabletop.reader import ParseError
    from tabletop.reader.reading import get_reader

    with pytest.raises(ParseError, match="out of range") as e:
        get_reader(reader).understand(text, robot)
    assert needle in str(e.value) and e.value.out_of_range


def test_an_llm_config_naming_a_key_variable_that_is_not_set_is_refused(tmp_path):
    path = tmp_path / "llm.toml"
    path.write_text('[llm]\nbase_url = "http://127.0.0.1:9/v1"\nmodel = "m"\napi_key_env = "K"\n')
    with pytest.raises(ConfigError, match="'K', which is not set"):
        LLMConfig.from_file(path, env={})
    with pytest.raises(ConfigError, match="not set"):
        LLMConfig.from_file(path, env={"K": ""})
    assert LLMConfig.from_file(path, env={"K": "secret"}).api_key == "secret"
    path.write_text('[llm]\nbase_url = "http://127.0.0.1:9/v1"\nmodel = "m"\n')
    assert LLMConfig.from_file(path, env={}).api_key is None  # a local endpoint: no key


def test_a_binary_task_file_is_named_not_a_codec_traceback(tmp_path, capsys):
    from tabletop.cli import main

    path = tmp_path / "binary.toml"
    path.write_bytes(bytes([0xC3, 0x28, 0xFF, 0x00, 0x9F]) * 20)
    assert main(["eval", str(path)]) == 2
    err = capsys.readouterr().err
    assert "binary.toml" in err and "not UTF-8 text" in err


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("[1,2,3]", "a JSON list, not an object"),
        ('{"not":"results"}', "no 'rows' list (its keys: not)"),
        ("", "the file is empty"),
        ('{"rows": [', "not valid JSON"),
        ('{"rows": [1]}', "rows[0] is not an object"),
    ],
)
def test_eval_compare_refuses_files_that_are_not_evaluation_results(tmp_path, capsys, text, needle):
    from tabletop.cli import main

    path = tmp_path / "r.json"
    path.write_text(text)
    assert main(["eval-compare", str(path), str(path)]) == 2
    err = capsys.readouterr().err
    assert "is not an evaluation results file" in err and needle in err and "r.json" in err
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "results.json").write_bytes(b"\xff\xfe\x00binary")
    assert main(["eval-compare", str(tmp_path / "d"), str(path)]) == 2
    assert "not UTF-8 text" in capsys.readouterr().err


def test_eval_compare_names_a_path_that_is_no_evaluation_output(tmp_path, capsys):
    # a bare "[Errno 2] No such file or directory" for each
    from tabletop.cli import main

    (tmp_path / "empty").mkdir()
    (tmp_path / "odd").mkdir()
    (tmp_path / "odd" / "results.json").mkdir()
    cases = [
        (tmp_path / "missing", "does not exist"),
        (tmp_path / "empty", "is a directory without results.json"),
        (tmp_path / "odd", "is a directory, not a file"),
    ]
    for path, needle in cases:
        assert main(["eval-compare", str(path), str(path)]) == 2
        err = capsys.readouterr().err
        assert err.startswith("tabletop eval-compare: error: "), err
        assert needle in err and str(path) in err and "Errno" not in err, err
        assert "an evaluation output directory holding results.json" in err, err


def test_a_file_that_is_not_weights_is_named_without_unsafe_loading_advice(tmp_path, capsys):
    # torch's refusal suggested weights_only=False, which would run the file's code
    import argparse

    import torch

    from tabletop.cli import main
    from tabletop.errors import AssetError
    from tabletop.reader.learned import load_tagger

    pickled = tmp_path / "pickled.pt"
    torch.save(argparse.Namespace(a=1), pickled)  # a pickle of a class: no weights file
    text = tmp_path / "text.pt"
    text.write_text("not weights at all")
    for path in (pickled, text):
        assert main(["check-encoders", "--vision-weights", str(path)]) == 2
        err = capsys.readouterr().err
        assert "is not a weights file of the expected format" in err and str(path) in err, err
        assert "weights_only" not in err and "--vision-weights" in err, err
        with pytest.raises(AssetError) as e:
            load_tagger(path)
        assert "is not a weights file" in str(e.value) and "weights_only" not in str(e.value)


def test_a_suite_file_that_is_a_directory_is_named_a_directory(tmp_path, capsys):
    # "suite file ... does not exist" for a directory that does
    from tabletop.cli import main

    for cmd in (["parse", "--suite"], ["run", "reference", "--suite"]):
        assert main([*cmd, "--suite-file", str(tmp_path)]) == 2
        err = capsys.readouterr().err
        assert "is a directory, not a file" in err and "does not exist" not in err, err


def test_a_suite_file_without_a_suite_to_score_is_refused(tmp_path, capsys):
    # the ninth probe: --suite-file without --suite was left unread without a word
    from tabletop.cli import main

    path = tmp_path / "suite.toml"
    path.write_text("not read")
    assert main(["parse", "go to the mug", "--suite-file", str(path)]) == 2
    assert "give --suite too" in capsys.readouterr().err
    assert main(["run", "some_map.npz", "go to the mug", "--suite-file", str(path)]) == 2
    err = capsys.readouterr().err
    assert "give --suite or the map 'reference'" in err and "some_map" not in err


def _default_scene_with(**changes) -> dict:
    """The shipped default scene's data with the first object's fields changed."""
    import tomllib

    from tabletop.sim.scene import default_scene_path

    data = tomllib.loads(default_scene_path().read_text())
    data["objects"][0].update(changes)
    return data


@pytest.mark.parametrize(
    ("field", "value"),
    [("yaw_deg", "twenty"), ("yaw_deg", True), ("position", ["0.4", 0.3]), ("position", 3)],
)
def test_a_scene_object_field_of_the_wrong_type_is_named(field, value):
    from tabletop.errors import SceneError
    from tabletop.sim.scene import SceneSpec

    with pytest.raises(SceneError, match=f"object 'red_mug': {field} must be"):
        SceneSpec.from_dict(_default_scene_with(**{field: value}), source="s.toml")


def test_a_scene_name_too_long_for_the_file_system_is_a_scene_error(capsys):
    from tabletop.cli import main

    assert main(["scenes", "a" * 5000]) == 2
    err = capsys.readouterr().err
    assert "5000 characters" in err and "cannot be looked up" in err and "default" in err


@pytest.mark.parametrize("objects", ["red mug", 5, ["red mug"]])
def test_scene_objects_that_are_not_a_list_of_tables_are_named(objects):
    from tabletop.errors import SceneError
    from tabletop.sim.scene import SceneSpec

    with pytest.raises(SceneError, match=r"objects.* not a table|objects must be a list of tables"):
        SceneSpec.from_dict({"objects": objects}, source="s.json")


def test_a_scene_object_on_the_robot_base_is_refused():
    from tabletop.errors import SceneError
    from tabletop.sim.scene import SceneSpec

    with pytest.raises(SceneError, match="'red_mug' at \\[0.0, 0.0\\] stands on the robot's base"):
        SceneSpec.from_dict(_default_scene_with(position=[0.0, 0.0]), source="s.toml")


def test_an_unknown_key_of_a_scene_object_is_refused_with_the_valid_keys():
    from tabletop.errors import SceneError
    from tabletop.sim.scene import SceneSpec

    with pytest.raises(SceneError, match=r"unknown keys \['bogus'\]; valid keys: \['name'"):
        SceneSpec.from_dict(_default_scene_with(bogus=3), source="s.toml")


@pytest.mark.parametrize(
    ("section", "where"),
    [("random", "[random]"), ("table", "[table]"), ("scene", "[scene]"), ("areas", "[[areas]] #1")],
)
def test_an_unknown_key_of_a_scene_table_is_named_with_its_table_and_the_valid_keys(section, where):
    # a Python TypeError "unexpected keyword argument" (or nothing, for [scene])
    from tabletop.errors import SceneError
    from tabletop.sim.scene import SceneSpec

    data = _default_scene_with()
    data["random"] = {"seed": 1, "count": 1}
    data["areas"] = [{"name": "corner", "x": [0.3, 0.4], "y": [0.1, 0.2]}]
    table = data.setdefault(section, {}) if section != "areas" else data["areas"][0]
    table["wobble"] = 2
    with pytest.raises(SceneError) as e:
        SceneSpec.from_dict(data, source="s.toml")
    msg = str(e.value)
    assert f"unknown key ['wobble'] in {where}; valid keys: [" in msg, msg
    assert "unexpected keyword" not in msg


@pytest.mark.parametrize("name", ["", "  "])
def test_an_empty_scene_object_name_is_refused(name):
    from tabletop.errors import SceneError
    from tabletop.sim.scene import SceneSpec

    with pytest.raises(SceneError, match="object name must be a non-empty string"):
        SceneSpec.from_dict(_default_scene_with(name=name), source="s.toml")


def test_sounds_refuses_an_empty_esc50_path(capsys, tmp_path, monkeypatch):
    from tabletop.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["sounds", "--esc50", ""]) == 2
    assert "--esc50 '' is empty" in capsys.readouterr().err


def test_rooms_refuses_a_room_name_together_with_generate(capsys):
    from tabletop.cli import main

    assert main(["rooms", "--generate", "3", "default"]) == 2
    err = capsys.readouterr().err
    assert "'default'" in err and "--generate 3" in err and "not both" in err


@pytest.mark.parametrize("tables", ["", ",,,", " , "])
def test_scan_room_refuses_a_tables_list_that_names_no_table(capsys, tmp_path, tables):
    from tabletop.cli import main

    out = tmp_path / "r1"
    assert main(["scan-room", "--out", str(out), "--tables", tables]) == 2
    err = capsys.readouterr().err
    assert "names no table" in err and "work_table" in err
    assert not out.exists()


def test_heatmap_arithmetic_other_than_fusing_two_heatmaps_is_refused_by_name(oracle_map):
    from tabletop.robot import MobileBase

    h = MobileBase(oracle_map).get_major_map(obj="mug")
    bad_ones = (
        lambda: h * 5,
        lambda: 5 * h,
        lambda: h * np.zeros((3, 3)),
        lambda: h + h,
        # numpy's operators defer to the heatmap's: no bare array comes back
        lambda: np.zeros((3, 3)) * h,
        lambda: np.float64(2.0) * h,
        lambda: np.ones(h.values.shape) - h,
        lambda: h**2,
        lambda: -h,
        lambda: h @ h,
        lambda: h > 0.5,
    )
    for bad in bad_ones:
        with pytest.raises(TypeError, match=r"Heatmap \S+ ?\w*.*only arithmetic on heatmaps"):
            bad()
    assert (h * h).values.shape == h.values.shape  # fusing two heatmaps still works


@pytest.mark.parametrize(
    ("setting", "needle"),
    [
        ("object.instances=maybe", "object.instances='maybe': expected true or false"),
        ("frame_step=2.5", "frame_step=2.5: expected an integer"),
        ("no.such.field=1", "unknown field; valid map fields: area, audio"),
        ("object.nope=1", "valid fields of object: background"),
    ],
)
def test_map_set_values_and_fields_are_checked_before_any_work(tmp_path, capsys, setting, needle):
    from tabletop.cli import main

    out = tmp_path / "out"
    assert main(["eval", "demo", "--map-set", setting, "--out", str(out), "--no-cache"]) == 2
    assert needle in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("", "the file is empty"),
        ("[[instructions]]\ntext = 5\n", "no [scene] table"),
        ('[scene]\nname = "default"\nstart = [0, 0, 0]\n', "no [[case]] tables"),
        ('[scene]\nname = "d"\nstart = [0, 0]\n[[case]]\nid = "a"\n', "start must be [x, y, z]"),
        ('[scene]\nname = "d"\nstart = [nan, 0, 0.3]\n[[case]]\nid = "a"\n', "three finite"),
        ('[scene]\nname = "d"\nstart = [0, 0, 0]\n[[case]]\nid = "a"\n', "#1 lacks family"),
    ],
)
def test_a_suite_file_without_what_a_suite_needs_says_what_it_needs(tmp_path, capsys, text, needle):
    from tabletop.cli import main
    from tabletop.language.suite import load_suite

    path = tmp_path / "suite.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match="a suite file is TOML with \\[scene\\]") as e:
        load_suite(path)
    assert needle in str(e.value)
    assert main(["parse", "--suite", "--suite-file", str(path)]) == 2
    assert needle in capsys.readouterr().err


def test_a_compass_move_of_no_or_negative_distance_is_refused_by_every_embodiment(oracle_map):
    from tabletop.language.run import TracingRobot
    from tabletop.language.suite import PointRobot
    from tabletop.robot import MobileBase
    from tabletop.robot.api import PrimitiveArgumentError

    want = r"move_north\(distance_m=...\): distance_m must be a number of metres in \(0, 1\]"
    base, point = MobileBase(oracle_map), PointRobot(oracle_map)
    tracer = TracingRobot(PointRobot(oracle_map), execute=True, start=(0.3, 0.0, 0.1))
    for robot in (base, point, tracer):
        start = robot.current_position()
        for bad in (-0.3, 0.0):
            with pytest.raises(PrimitiveArgumentError, match=want):
                robot.move_north(bad)
        np.testing.assert_array_equal(robot.current_position(), start)  # nothing moved
    for robot in (base, point):
        with pytest.raises(PrimitiveArgumentError, match=want):
            robot.move_north(1.5)
    assert base.move_north(0.1).reached


def test_the_point_robot_refuses_a_target_off_the_map(oracle_map):
    from tabletop.language.run import TracingRobot
    from tabletop.language.suite import PointRobot
    from tabletop.robot.api import TargetOffMap

    p = PointRobot(oracle_map)
    with pytest.raises(TargetOffMap, match=r"move_to: the target .* lies outside the map \(x -0.2"):
        p.move_to((1e6, 1e6, 1e6))
    t = TracingRobot(PointRobot(oracle_map), execute=True, start=(0.3, 0.0, 0.3))
    with pytest.raises(TargetOffMap, match=r"outside the map"):
        t.move_north(0.9)  # x = 1.2 m, off the table
    np.testing.assert_allclose(t.current_position(), [0.3, 0.0, 0.3])
    p.move_to((0.5, 0.1, 0.1))
    np.testing.assert_allclose(p.current_position(), [0.5, 0.1, 0.1])


def test_an_arm_target_inside_its_own_base_is_refused(oracle_map):
    from tabletop.robot.api import PrimitiveArgumentError
    from tabletop.robot.arm import SimArm

    arm = SimArm(oracle_map, "default")
    try:
        q0 = arm.world.arm_q()
        with pytest.raises(PrimitiveArgumentError, match=r"inside the robot's own base"):
            arm.move_to([0.0, 0.0, 0.05])
        np.testing.assert_array_equal(arm.world.arm_q(), q0)
    finally:
        arm.close()


def test_a_base_starting_off_the_map_is_refused_naming_its_bounds(oracle_map):
    from tabletop.robot import MobileBase

    with pytest.raises(ConfigError, match=r"start \(50, 50\) m lies off the map.*x -0.2 .. 0.8"):
        MobileBase(oracle_map, start=(50, 50))
    MobileBase(oracle_map, start=(0.15, 0.0))


def test_between_a_landmark_and_itself_is_refused(oracle_map):
    from tabletop.language.run import TracingRobot
    from tabletop.language.suite import PointRobot
    from tabletop.robot import MobileBase
    from tabletop.robot.api import PrimitiveArgumentError

    tracer = TracingRobot(PointRobot(oracle_map), execute=True, start=(0.3, 0.0, 0.1))
    for robot in (MobileBase(oracle_map), PointRobot(oracle_map), tracer):
        with pytest.raises(PrimitiveArgumentError, match=r"'red mug' .* are the same thing"):
            robot.move_in_between("red mug", "red mug")


def _two_mugs():
    """Two frames from 0.5 m above the table looking down: a red mug and a blue mug 20 cm
    apart (8 cm boxes)."""
    from helpers import ground_truth_dict

    from tabletop.recording import Recording

    n, w, h = 2, 320, 240
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = np.diag([1.0, -1.0, -1.0])
    T[:, 0, 3], T[:, 2, 3] = 0.4, 0.5
    depth = np.full((n, h, w), 0.5, np.float32)
    seg = np.full((n, h, w), 2, np.uint16)
    rgb = np.full((n, h, w, 3), 200, np.uint8)
    boxes = []
    for k, (name, colour, u) in enumerate(
        (("red_mug", (200, 20, 20), 70), ("blue_mug", (20, 20, 200), 230))
    ):
        depth[:, 100:140, u - 20 : u + 20] = 0.42
        seg[:, 100:140, u - 20 : u + 20] = 4 + k
        rgb[:, 100:140, u - 20 : u + 20] = colour
        x = 0.4 + (u - 160) / 200 * 0.5
        boxes.append(
            {"name": name, "aabb_min": [x - 0.05, -0.05, 0.0], "aabb_max": [x + 0.05, 0.05, 0.08]}
        )
    gt = ground_truth_dict(objects=boxes)
    gt["scene"] = load_scene_spec("default").to_dict()
    K = np.array([[200.0, 0, 160], [0, 200.0, 120], [0, 0, 1]])
    return Recording(
        timestamps=np.arange(n) / 30.0, rgb=rgb, depth=depth, joint_positions=np.zeros((n, 7)),
        T_world_hand=T, K=K, T_hand_cam=np.eye(4), segmentation=seg, ground_truth=gt,
        meta={"source": "test", "scene": "default"},
    )  # fmt: skip


def test_between_two_names_that_find_one_thing_takes_the_next_thing_for_one_of_them():
    from tabletop.eval.harness import build_map, map_config
    from tabletop.language.suite import PointRobot
    from tabletop.robot.api import PrimitiveArgumentError

    robot = PointRobot(build_map(_two_mugs(), "oracle", map_config(visual=None)))
    red, blue = robot.get_pos("red mug"), robot.get_pos("blue mug")
    assert np.linalg.norm(red[:2] - blue[:2]) > 0.1
    # "the mug" finds one of the two, as its coloured name does: said apart, they are both
    plain = "red mug" if np.allclose(robot.get_pos("mug"), red) else "blue mug"
    want = robot.between("red mug", "blue mug")
    for a, b in ((plain, "mug"), ("mug", plain)):
        assert np.allclose(robot.between(a, b)[:2], want[:2], atol=0.01), (a, b)
    # the same words are one thing
    with pytest.raises(PrimitiveArgumentError, match="are the same thing"):
        robot.between("mug", "mug")


def test_a_sim_arm_in_another_scene_than_the_maps_is_refused_or_warned(oracle_map):
    from tabletop.robot.arm import SimArm

    assert (oracle_map.source or {}).get("scene_fingerprint")
    with pytest.raises(ConfigError, match=r"built from scene 'default'.*not from scene 'random'"):
        SimArm(oracle_map, "random")
    with pytest.warns(UserWarning, match="other_scene=True"):
        arm = SimArm(oracle_map, "random", other_scene=True)
    try:
        assert "WARNING (other_scene)" in arm.move_to([0.4, 0.0, 0.2]).note
    finally:
        arm.close()


def test_empty_vision_weights_name_the_reason(tmp_path, capsys):
    from tabletop.cli import main

    path = tmp_path / "empty.pt"
    path.write_bytes(b"")
    assert main(["check-encoders", "--vision-weights", str(path)]) == 2
    err = capsys.readouterr().err
    assert "empty.pt are unreadable: the file is empty (0 bytes)" in err


@pytest.mark.parametrize(
    ("flags", "needle"),
    [
        (["--hand-cam", "bad.txt"], "--hand-cam: BAD must hold 4x4 numbers"),
        (["--hand-cam", "nan.json"], "holds non-finite numbers"),
        (["--hand-cam", "scaled.json"], "is not a rigid transform"),
        (["--intrinsics", "0", "1", "2", "3"], "--intrinsics FX FY CX CY"),
        (["--max-pair-dt", "-1"], "--max-pair-dt must be a finite number of seconds > 0"),
        (["--pose-time-offset", "nan"], "--pose-time-offset must be a finite number"),
    ],
)
def test_import_flags_are_checked_before_anything_is_read(tmp_path, capsys, flags, needle):
    from tabletop.cli import main

    (tmp_path / "bad.txt").write_text("4x4 matrix nope\n")
    (tmp_path / "nan.json").write_text("[[NaN,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]")
    (tmp_path / "scaled.json").write_text("[[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]")
    flags = [str(tmp_path / f) if f.endswith((".txt", ".json")) else f for f in flags]
    out = tmp_path / "rec"
    assert main(["import", str(tmp_path / "src"), "--out", str(out), *flags]) == 2
    err = capsys.readouterr().err
    assert needle.replace("BAD", str(tmp_path / "bad.txt")) in err and not out.exists()


@pytest.mark.parametrize("host", ["not a host", "", "1.2.3", "bad-.example", "a_b"])
def test_view_refuses_a_host_that_is_no_address_or_hostname_before_serving(tmp_path, capsys, host):
    from tabletop.cli import main

    # checked before the map is even looked at (the map here does not exist)
    assert main(["view", str(tmp_path / "none.npz"), "--host", host]) == 2
    err = capsys.readouterr().err
    assert f"--host {host!r} is neither an IP address nor a hostname" in err and "0.0.0.0" in err


def test_query_with_the_llm_reader_takes_the_endpoint_flags_its_message_names(
    tmp_path, capsys, monkeypatch
):
    from tabletop.cli import main

    for var in ("TABLETOP_LLM_BASE_URL", "TABLETOP_LLM_MODEL", "TABLETOP_LLM_API_KEY"):
        monkeypatch.delenv(var, raising=False)
    q = ["query", str(tmp_path / "none.npz"), "--obj", "red mug"]
    assert main([*q, "--reader", "llm", "--llm-model", "m"]) == 2
    err = capsys.readouterr().err
    assert "needs base_url" in err and "TABLETOP_LLM_BASE_URL" in err and "--llm-url" in err
    assert main([*q, "--llm-url", "http://127.0.0.1:9/v1"]) == 2
    assert "--llm-url: only with --reader llm" in capsys.readouterr().err
    # given both, the reader is made and the map is what is refused next
    llm = ["--reader", "llm", "--llm-url", "http://127.0.0.1:9/v1", "--llm-model", "m"]
    assert main([*q, *llm]) == 2
    err = capsys.readouterr().err
    assert "none.npz" in err
    # and it says that a query's words are read here, not by the endpoint
    assert "reader llm: a query's words are read here" in err


def test_parse_refuses_endpoint_flags_it_would_ignore(capsys):
    from tabletop.cli import main

    assert main(["parse", "go to the mug", "--llm-url", "http://127.0.0.1:9/v1"]) == 2
    assert "--llm-url: only with --backend llm" in capsys.readouterr().err
    assert main(["parse", "go to the mug"]) == 0


def test_a_place_beneath_the_table_or_the_floor_is_not_found_on_its_top(oracle_map):
    from tabletop.mapping.object_module import BACKGROUND
    from tabletop.reader.places import SURFACES
    from tabletop.reader.reading import get_reader

    assert set(SURFACES) <= set(BACKGROUND)  # the map's own surfaces, not a list of places
    reader = get_reader()
    for words in ("under the table", "below the floor", "somewhere beneath the tabletop"):
        h = oracle_map.area_heatmap(reader.reference("area", words))
        assert not h.found, words
        assert "beneath the top is off it" in h.reason, h.reason
    # beneath a thing on the table is where that thing stands: read on, as before
    ref = reader.reference("area", "the bit of table under the tray")
    assert ref.subject is not None and "tray" in ref.subject
    # the plain regions still read
    assert reader.reference("area", "the left side of the table").region is not None


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["eval", "demo", "--goals"], "--goals adds every goal to --json's output"),
        (["run", "m.npz", "go to the mug", "--json"], "--json is the suite's report"),
        (["parse", "go to the mug", "--json"], "--json is the suite's report"),
        (["run", "m.npz", "go to the mug", "--image-dir", "/no/such/dir"], "does not exist"),
        (["run", "m.npz", "go to the mug", "--image-dir", "FILE"], "is not a directory"),
    ],
)
def test_flags_that_would_be_ignored_are_refused_before_any_work(tmp_path, capsys, argv, needle):
    from tabletop.cli import main

    f = tmp_path / "f.txt"
    f.write_text("x")
    argv = [str(f) if a == "FILE" else a for a in argv]
    if argv[0] == "eval":
        argv += ["--out", str(tmp_path / "out")]
    assert main(argv) == 2
    assert needle in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_colour_name_alone_asks_for_something_of_that_colour_unless_it_names_a_thing(
    oracle_map,
):
    om = oracle_map.objects
    # "purple" names nothing: something purple (found only where a purple thing stands)
    assert om.readings("purple") == [("purple", "something")]
    assert om.readings("the purple") == [("purple", "something")]
    # "the orange" names a fruit: read as the thing first, as before
    assert om.readings("the orange")[0] == ("", "the orange")
    # a colour with a thing is unchanged
    assert om.readings("the purple mug")[0] == ("purple", "the mug")


def test_the_maps_background_asked_as_an_object_is_named_as_the_background(oracle_map):
    for words in ("the table", "floor", "the robot arm"):
        h = oracle_map.object_heatmap(words)
        assert not h.found and "is the map's background" in h.reason, h.reason
    # anything else still says what it is nearest
    assert "like nothing in this map's vocabulary" in oracle_map.object_heatmap("tablecloth").reason


def test_query_pictures_are_not_replaced_without_overwrite(tmp_path, capsys):
    from tabletop.cli.app import main

    out = tmp_path / "q"
    top = tmp_path / "q_top.png"
    top.write_bytes(b"an earlier picture")
    code = main(["query", str(tmp_path / "none.npz"), "--obj", "mug", "--out", str(out)])
    assert code == 2 and "pass --overwrite" in capsys.readouterr().err
    assert top.read_bytes() == b"an earlier picture"  # checked before the map is read


def test_train_refuses_a_thread_or_step_count_below_one(capsys):
    from tabletop.cli.app import main

    for argv in (["train", "reader", "--threads", "0"], ["train", "audio", "--steps", "-3"]):
        assert main(argv) == 2
        assert "must be a positive whole number" in capsys.readouterr().err


def test_a_side_direction_that_picks_no_side_is_named(oracle_map):
    from tabletop.language.suite import PointRobot
    from tabletop.robot.api import PrimitiveArgumentError, check_axis

    p = PointRobot(oracle_map)
    name = oracle_map.config.objects[0]
    # these gave the landmark's centre (zero), a NaN target, or numpy's ValueError ("left")
    for bad in [(0, 0, 0), (np.nan, 1, 0), "left", (1, 1), (0, 0, 1)]:
        with pytest.raises(PrimitiveArgumentError, match=r"side_target\(direction=\.\.\.\)"):
            p.side_target(name, bad)
    np.testing.assert_array_equal(check_axis("side_target", (0, 1)), [0.0, 1.0, 0.0])
    assert np.isfinite(p.side_target(name, (0, 1, 0))).all()


def test_eval_refuses_contradictory_cache_flags_and_a_task_file_given_twice(capsys):
    from tabletop.cli.app import main
    from tabletop.eval.runner import collect_task_files
    from tabletop.eval.tasks import TaskFileError

    for cmd in (["eval", "demo"], ["calibrate"]):
        assert main([*cmd, "--no-cache", "--cache-dir", "somewhere"]) == 2
        assert "--no-cache and --cache-dir 'somewhere' exclude each other" in (
            capsys.readouterr().err
        )
    with pytest.raises(TaskFileError, match="is given twice"):
        collect_task_files(["demo", "demo"])
    assert len(collect_task_files(["demo"])) == 1


def test_run_checks_its_llm_config_before_the_map_and_the_robot(tmp_path, capsys):
    from tabletop.cli import main

    # the map does not exist either: the config's problem must be the one named
    argv = ["run", str(tmp_path / "none.npz"), "go to the mug", "--backend", "llm"]
    assert main([*argv, "--llm-config", str(tmp_path / "missing.toml")]) == 2
    err = capsys.readouterr().err
    assert "missing.toml" in err and "none.npz" not in err
    assert "starting the simulated arm" not in err


@pytest.mark.parametrize("encoders", ["oracle", "default"])
def test_a_map_is_built_from_a_recording_or_its_path_and_nothing_else(tmp_path, encoders):
    from tabletop.eval.harness import build_map

    # the default set had raised an AttributeError; the oracle had blamed the ground truth
    for bad in (None, 3, [tmp_path]):
        with pytest.raises(ConfigError, match="a map is built from a Recording"):
            build_map(bad, encoders)
    (tmp_path / "notes.txt").write_text("x")
    for path, why in (
        (tmp_path / "nothing", "does not exist"),
        (tmp_path / "notes.txt", "is a file, not a recording"),
        (tmp_path, "is not a recording"),
    ):
        with pytest.raises(RecordingError, match=why):
            build_map(str(path), encoders)
