"""Nothing crashes, nothing lies: the bad inputs of issue 44, each a clear error or an honest
result, through the real command line (``main(argv)`` in-process), the real loaders and the
real simulated arm.

A small synthetic recording of the default table (six frames looking down on the table and a
box labelled ``red_mug``, with the default scene's spec as its ground truth) keeps the maps
built here to a second each.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from helpers import ground_truth_dict

from tabletop.atomic import check_writable
from tabletop.cli import main
from tabletop.errors import ConfigError, RecordingError
from tabletop.mapping.persistence import (
    MapFormatError,
    check_map_fingerprints,
    check_map_scene,
    read_map_file,
)
from tabletop.recording import Recording, load_recording, save_recording
from tabletop.sim.scene import load_scene_spec


def small_recording(n: int = 6) -> Recording:
    """Six frames from 0.5 m above the table (z = 0) looking down, a 8 cm box in view."""
    w, h = 320, 240
    K = np.array([[200.0, 0, 160], [0, 200.0, 120], [0, 0, 1]])
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = np.diag([1.0, -1.0, -1.0])  # optical axis down
    T[:, 0, 3] = 0.3 + 0.04 * np.arange(n)
    T[:, 2, 3] = 0.5
    depth = np.full((n, h, w), 0.5, np.float32)
    seg = np.full((n, h, w), 2, np.uint16)  # the table
    depth[:, 100:140, 140:180] = 0.42
    seg[:, 100:140, 140:180] = 4  # the box
    box = {"name": "red_mug", "aabb_min": [0.28, -0.02, 0.0], "aabb_max": [0.52, 0.02, 0.08]}
    gt = ground_truth_dict(objects=[box])
    gt["scene"] = load_scene_spec("default").to_dict()
    return Recording(
        timestamps=np.arange(n) / 30.0,
        rgb=np.random.default_rng(0).integers(0, 256, (n, h, w, 3), dtype=np.uint8),
        depth=depth,
        joint_positions=np.zeros((n, 7)),
        T_world_hand=T,
        K=K,
        T_hand_cam=np.eye(4),
        segmentation=seg,
        ground_truth=gt,
        meta={"source": "test", "scene": "default"},
    )


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """(recording dir, oracle map path) built by ``tabletop build-map``."""
    d = tmp_path_factory.mktemp("built")
    rec = save_recording(small_recording(), d / "rec")
    assert main(["build-map", str(rec), "--out", str(d / "oracle.npz")]) == 0
    return rec, d / "oracle.npz"


def run(capsys, *argv: str) -> tuple[int, str]:
    rc = main([str(a) for a in argv])
    out = capsys.readouterr()
    return rc, out.out + out.err


# ---------------------------------------------------------------------- unwritable outputs
def _unwritable(tmp_path: Path) -> list[tuple[str, str]]:
    """(path, why) of outputs that cannot be written."""
    afile = tmp_path / "file.txt"
    afile.write_text("mine")
    return [
        (f"{afile}/x.npz", "is a file, not a directory"),
        ("/proc/tabletop-x.npz", "does not take new files"),
        ("/proc/tabletop-d/x.npz", "does not take new files"),
    ]


@pytest.mark.parametrize(
    "argv",
    [
        ["build-map", "NO_RECORDING", "--out", "OUT"],
        ["query", "NO_MAP.npz", "--obj", "mug", "--out", "OUT"],
        ["scan", "--out", "OUT"],
        ["scan-room", "--out", "OUT"],
        ["eval", "demo", "--out", "OUT"],
        ["eval", "demo", "--cache-dir", "OUT"],
        ["demo", "--out", "OUT"],
        ["calibrate", "--out", "OUT"],
        ["train", "audio", "--out", "OUT"],
        ["train", "reader", "--out", "OUT"],
        ["check-encoders", "--cache-dir", "OUT"],
    ],
    ids=lambda a: "-".join(a[:2]),
)
def test_an_output_that_cannot_be_written_fails_before_any_work(tmp_path, capsys, argv):
    for out, why in _unwritable(tmp_path):
        args = [
            out if a == "OUT" else str(tmp_path / a) if a.startswith("NO_") else a for a in argv
        ]
        rc, text = run(capsys, *args)
        assert rc == 2, (args, text)
        assert "Traceback" not in text and why in text, (args, text)
        assert out.split("/")[-2] in text  # the message names the path
        assert "loading" not in text and "scanning" not in text  # nothing was started
    assert (tmp_path / "file.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt"]  # nothing left behind


def test_the_one_writable_check_names_empty_long_and_directory_paths(tmp_path):
    with pytest.raises(ConfigError, match="--out path is empty"):
        check_writable("", what="--out")
    with pytest.raises(ConfigError, match="longer than 255 bytes"):
        check_writable(tmp_path / ("x" * 300))
    with pytest.raises(ConfigError, match="is a directory; give a file path"):
        check_writable(tmp_path)
    assert check_writable(tmp_path / "new" / "deeper" / "m.npz") == tmp_path / "new/deeper/m.npz"
    assert list(tmp_path.iterdir()) == []  # the check leaves nothing behind
    if os.geteuid() != 0:  # root writes into read-only directories
        ro = tmp_path / "ro"
        ro.mkdir(mode=0o500)
        with pytest.raises(ConfigError, match="does not take new files"):
            check_writable(ro / "m.npz")


# ---------------------------------------------------------------------- recording headers
@pytest.mark.parametrize(
    "header, words",
    [
        (b"[1, 2]", "holds a JSON array, not an object"),
        (b'"tabletop-recording"', "holds a JSON string, not an object"),
        (b"null", "holds a JSON null, not an object"),
        (b"3.5", "holds a JSON number, not an object"),
        (b"\xff\xfe\x00\x01", "is not text (byte 0 is not UTF-8)"),
        (b"[" * 100_000, "nests JSON too deeply"),
    ],
)
def test_a_recording_header_that_is_not_a_json_object_is_named(tmp_path, capsys, header, words):
    rec = tmp_path / "rec"
    rec.mkdir()
    (rec / "recording.json").write_bytes(header)
    with pytest.raises(RecordingError, match="recording.json") as e:
        load_recording(rec)
    assert words in str(e.value)
    rc, text = run(capsys, "build-map", rec, "--out", tmp_path / "m.npz")
    assert rc == 2 and words in text and "Traceback" not in text


# ---------------------------------------------------------------------- robot API types
def test_every_primitive_names_a_wrong_argument_and_a_closed_robot_refuses(built):
    from tabletop.mapping import AVLMap
    from tabletop.robot import SimArm
    from tabletop.robot.api import PrimitiveArgumentError, RobotClosed
    from tabletop.robot.primitives import PRIMITIVES

    arm = SimArm(AVLMap.load(built[1]), "default")
    with arm:
        for call, args in (
            ("move_north", ("5",)),
            ("move_south", (True,)),
            ("move_west", (float("inf"),)),
            ("move_to", ("0.4, 0, 0.1",)),
            ("move_to", ([0.4, "0", 0.1],)),
            ("move_to_left", (5,)),
            ("move_in_between", ("red mug", None)),
            ("get_max_pos_3d", (np.zeros(3),)),
            ("offset", ("1", 0)),
            ("get_map", ()),
        ):
            kwargs = {"obj": 3} if call == "get_map" else {}
            with pytest.raises(PrimitiveArgumentError) as e:
                getattr(arm, call)(*args, **kwargs)
            assert isinstance(e.value, TypeError) and isinstance(e.value, ValueError)
            assert str(e.value).startswith(f"{call}(") and "must be" in str(e.value)
        # every declared primitive of the arm goes through the one check
        for p in PRIMITIVES:
            if not p.available_to("arm") or not p.params:
                continue
            bad = {n: object() for n in p.params[:1]}
            with pytest.raises(PrimitiveArgumentError, match=f"{p.params[0]} must be"):
                getattr(arm, p.name)(**bad)
        assert arm.history == []  # nothing moved
    for call, args in (("move_north", (0.1,)), ("current_position", ()), ("above", ("mug",))):
        with pytest.raises(RobotClosed, match="was closed"):
            getattr(arm, call)(*args)
    arm.close()  # a second close is harmless


# ---------------------------------------------------------------------- honest reaches
def test_a_target_below_the_table_is_not_reported_as_reached(built):
    from tabletop.mapping import AVLMap
    from tabletop.robot import SimArm

    with SimArm(AVLMap.load(built[1]), "default") as arm:
        r = arm.move_to((0.5, 0.0, -0.3))  # 0.3 m below the table's top
        assert not r.reached and r.reason.value == "outside_workspace"
        np.testing.assert_allclose(r.requested, (0.5, 0.0, -0.3))
        assert r.requested_error_m > 0.3
        assert "0.30 m below the table's top" in r.note and "nothing moved" in r.note
        assert r.steps == 0
        r = arm.move_to((0.3, -0.15, -0.02))  # in the table's top: raised within the radius
        assert "asked (+0.300, -0.150, -0.020) m, commanded (+0.300, -0.150, +0.0" in r.note
        assert "raised" in r.note and r.reached == (r.reason.value == "reached")
        np.testing.assert_allclose(r.requested, (0.3, -0.15, -0.02))
        r = arm.move_to((0.3, 0.1, 0.3))  # in free space: nothing to explain
        assert r.reached and r.note == "" and r.requested_error_m < 0.02


# ---------------------------------------------------------------------- LLM settings
@pytest.mark.parametrize(
    "toml, words",
    [
        ('llm = "http://127.0.0.1:8000/v1"\n', "'llm' is a str"),
        ("llm = 3\n", "'llm' is a int"),
        ('[llm]\nbase_url = "http://h:8000/v1"\nmodel = "m"\nmax_tokens = 1.5e400\n',
         "max_tokens must be an integer >= 1, got float inf"),
        ('[llm]\nbase_url = "http://h:8000/v1"\nmodel = 7\n', "model must be a string"),
        ('[llm]\nbase_url = "http://h:8000/v1"\nmodel = "m"\ntimeout_s = "soon"\n',
         "timeout_s must be a number of seconds"),
        ('[llm]\nbase_url = "http://h:99999/v1"\nmodel = "m"\n',
         "port must be a number in 1-65535"),
    ],
)  # fmt: skip
def test_llm_settings_name_the_field_and_the_valid_form(tmp_path, capsys, toml, words):
    f = tmp_path / "llm.toml"
    f.write_text(toml)
    rc, text = run(capsys, "parse", "go to the mug", "--backend", "llm", "--llm-config", f)
    assert rc == 2 and words in text and "Traceback" not in text, text


@pytest.mark.parametrize("url", ["http://127.0.0.1:99999/v1", "http://127.0.0.1:0/v1"])
def test_an_llm_url_port_out_of_range_is_named(capsys, url):
    rc, text = run(capsys, "parse", "go", "--backend", "llm", "--llm-url", url, "--llm-model", "m")
    assert rc == 2 and "port must be a number in 1-65535" in text and url in text


# ---------------------------------------------------------------------- queries of no words
@pytest.fixture(scope="module")
def default_map(built):
    """The default encoders' map of the same recording."""
    from tabletop.eval.harness import build_map, map_config

    m = build_map(load_recording(built[0]), "default", map_config(visual=None))
    return m.save(built[1].with_name("default.npz"))


def test_a_query_of_no_words_is_not_found_on_oracle_and_default_maps(built, default_map, capsys):
    for path in (built[1], default_map):
        for text in ("🦒🦒", "...", "123", "?!"):
            for flag in ("--obj", "--sound", "--area"):
                rc, out = run(capsys, "query", path, flag, text)
                assert rc == 1 and "NOT FOUND" in out and "target:   none" in out, out
                assert "holds no words" in out
    rc, out = run(capsys, "query", built[1], "--obj", "red mug")  # a word is still found
    assert rc == 0 and " found" in out


# ---------------------------------------------------------------------- map and scene
def test_a_map_is_refused_in_a_scene_it_was_not_built_from(built, capsys):
    h, _ = read_map_file(built[1])
    assert h["source"]["scene"] == "default" and h["source"]["scene_fingerprint"]
    rc, out = run(capsys, "run", built[1], "go to the red mug", "--scene", "random")
    assert rc == 2 and "was built from scene 'default'" in out and "--other-scene" in out
    assert "starting the simulated arm" not in out  # refused before the arm started
    other = load_scene_spec("random").to_dict()
    with pytest.raises(MapFormatError, match="not from --scene 'random'"):
        check_map_scene(built[1], h["source"], other, "random")
    check_map_scene(built[1], h["source"], load_scene_spec("default").to_dict(), "default")
    with pytest.raises(MapFormatError, match="does not record the scene"):
        check_map_scene(built[1], {}, other, "random")
    # a header whose scene name was edited to the one asked: named as another scene of that
    # name, not as "built from scene 'random' ... not from --scene 'random'"
    edited = {**h["source"], "scene": "random"}
    with pytest.raises(MapFormatError, match="names its scene 'random' as --scene does, but"):
        check_map_scene(built[1], edited, other, "random")
    # a file that is no map, read the viewer's quick way, is named as no map
    from tabletop.mapping.persistence import read_map_preview

    junk = built[1].parent / "junk.npz"
    np.save(junk.with_suffix(".npy"), np.array([{"a": 1}], dtype=object), allow_pickle=True)
    junk.with_suffix(".npy").rename(junk)
    with pytest.raises(MapFormatError, match="is not a map file: a map is a .npz archive"):
        read_map_preview(junk)


def test_other_scene_runs_a_map_in_another_scene_with_a_warning(built, capsys):
    # the flag passed the command's check, and the simulated arm then refused the map
    rc, out = run(capsys, "run", built[1], "go to the red mug", "--scene", "random",
                  "--other-scene")  # fmt: skip
    assert rc in (0, 1) and "WARNING" in out and "was built from scene 'default'" in out, out
    assert "reached" in out or "not reached" in out


def test_a_dry_run_checks_the_scene_against_the_map_as_a_run_does(built, capsys):
    # the dry run used to exit 0 without a word about a map built from another scene
    rc, out = run(capsys, "run", built[1], "go to the red mug", "--dry-run", "--scene", "random")
    assert rc == 2 and "was built from scene 'default'" in out and "--other-scene" in out
    rc, out = run(
        capsys,
        "run",
        built[1],
        "go to the red mug",
        "--dry-run",
        "--scene",
        "random",
        "--other-scene",
    )
    assert rc == 0 and "WARNING" in out
    rc, out = run(capsys, "run", built[1], "go to the red mug", "--dry-run")
    assert rc == 0 and "WARNING" not in out


def _with_header(src: Path, dst: Path, change) -> Path:
    with np.load(src, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    h = json.loads(arrays["header"].tobytes().decode())
    change(h)
    arrays["header"] = np.frombuffer(json.dumps(h).encode(), np.uint8)
    np.savez(dst, **arrays)
    return dst


def test_a_map_whose_encoder_fields_were_edited_is_refused(built, default_map, tmp_path, capsys):
    def to_default(h):
        h["encoder_set"] = "default"

    def rename(h):
        h["encoders"]["set"] = "default (embedded learned encoders)"
        h["encoder_set"] = "default"

    def rebuild(h):
        h["rebuild"]["labels"]["4"] = "blue_mug"

    def version(h):  # it loaded without a word, as a map of another version
        h["version"] = 4

    def scene(h):  # ... and as a map of another scene
        h["source"]["scene"] = "random"

    whole = "its header does not match the fingerprint written with the map"
    for change, words in (
        (to_default, "'encoder_set' is 'default' but its encoders are 'oracle"),
        (rename, "do not match the fingerprint written with the map"),
        (rebuild, "do not match the fingerprint written with the map"),
        (version, whole),
        (scene, whole),
    ):
        edited = _with_header(built[1], tmp_path / f"{change.__name__}.npz", change)
        rc, out = run(capsys, "query", edited, "--obj", "red mug")
        assert rc == 2 and words in out and "Traceback" not in out, out
    h, _ = read_map_file(default_map)  # its weights' fingerprints are checked on load
    assert set(h["fingerprints"]["weights"]) == {"vision", "audio"}
    weights = {**h["fingerprints"]["weights"], "vision": "0" * 16}  # as if retrained since
    changed = {**h, "fingerprints": {**h["fingerprints"], "weights": weights}}
    with pytest.raises(MapFormatError, match="vision weights .*vision_dense_effnet.pt.* changed"):
        check_map_fingerprints("m.npz", changed)


# ---------------------------------------------------------------------- sparse maps
def test_a_pixel_step_that_keeps_a_few_voxels_is_refused_or_warned(built, tmp_path, capsys):
    rc, out = run(capsys, "build-map", built[0], "--out", tmp_path / "m.npz", "--pixel-step", "100")
    assert rc == 2 and "keeps 12 pixels of each 320x240 frame, fewer than 100" in out
    assert "valid: 1 to 29" in out and not (tmp_path / "m.npz").exists()
    assert "loading" not in out  # refused from the header, before the frames load
    rc, out = run(capsys, "build-map", built[0], "--out", tmp_path / "m.npz", "--pixel-step", "29")
    assert rc == 1 and "warning: the map holds" in out and "fewer than 1000" in out


# ---------------------------------------------------------------------- unclear errors
def test_inputs_of_the_wrong_kind_are_named_for_what_they_are(tmp_path, capsys):
    (tmp_path / "adir.npz").mkdir()
    (tmp_path / "pickle.npz").write_bytes(b"\x80\x04K\x01.")  # a pickle, not a zip
    for argv, words in (
        (["query", tmp_path / "adir.npz", "--obj", "mug"], "is a directory, not a file"),
        (["query", "", "--obj", "mug"], "map file '' is empty"),
        (["query", tmp_path / "pickle.npz", "--obj", "mug"], "is not a map file"),
        (["run", tmp_path / "adir.npz", "go to the mug"], "is a directory, not a file"),
        (["scenes", tmp_path], "is a directory, not a file"),
        (["scenes", ""], "scene spec is empty"),
        (["build-map", tmp_path / "r", "--out", ""], "--out path is empty"),
        (["parse", "go to the mug", "--suite"], "give an instruction or --suite, not both"),
    ):
        rc, out = run(capsys, *argv)
        assert rc == 2 and words in out and "Traceback" not in out, (argv, out)
        assert "allow_pickle" not in out and "not found" not in out


@pytest.mark.parametrize("near", ["--near-obj", "--near-sound", "--near-area"])
def test_a_landmark_alone_is_refused_before_the_map_loads(tmp_path, capsys, near):
    # the map does not exist: the refusal must come first, naming the flag and the fix
    rc, text = run(capsys, "query", str(tmp_path / "no_map.npz"), near, "the mug")
    assert rc == 2 and "Traceback" not in text, text
    assert f"{near} only narrows a target" in text and "--obj" in text, text
    assert "no_map" not in text  # not a complaint about the map: it was never opened


def test_api_calls_given_the_wrong_kind_of_object_name_it(tmp_path):
    from tabletop.errors import RecordingError
    from tabletop.recording import save_recording
    from tabletop.sim.scan import ScanConfig, run_scan

    # these reached an AttributeError / TypeError deep inside
    with pytest.raises(ConfigError, match="run_scan scans a SceneSpec.*got str"):
        run_scan("default", ScanConfig())
    with pytest.raises(ConfigError, match="config must be a ScanConfig or None, got dict"):
        from tabletop.sim.scene import load_scene_spec

        run_scan(load_scene_spec("default"), {"episodes": 1})
    with pytest.raises(RecordingError, match="writes a Recording, got NoneType"):
        save_recording(None, tmp_path / "zz")
    assert list(tmp_path.iterdir()) == []
