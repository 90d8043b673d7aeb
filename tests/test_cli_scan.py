"""Tests of tabletop.cli.scan: ``tabletop scan`` (no bars when stdout is not a terminal),
``tabletop sounds`` and its table, ``tabletop scenes``."""

from __future__ import annotations

import json

import numpy as np
from helpers import ground_truth_dict

from tabletop.cli import main
from tabletop.cli.scan import format_bank_table
from tabletop.recording import Recording, Segment, load_recording
from tabletop.sim.scan import ScanStats
from tabletop.sim.sound_bank import SoundBank


def _tiny_recording(n: int = 3) -> Recording:
    rng = np.random.default_rng(0)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, 3] = [0.3, 0.0, 0.4]
    return Recording(
        timestamps=np.arange(n) / 30.0,
        rgb=rng.integers(0, 256, (n, 240, 320, 3), dtype=np.uint8),
        depth=np.full((n, 240, 320), 0.4, np.float32),
        joint_positions=np.zeros((n, 7)),
        T_world_hand=T,
        K=np.array([[200.0, 0, 159.5], [0, 200.0, 119.5], [0, 0, 1]]),
        T_hand_cam=np.eye(4),
        segments=(Segment("mapping", "mapping", 0, n),),
        ground_truth=ground_truth_dict(
            sound_events=[{"category": "dog", "onset_s": 0.0, "table_point": [0.4, 0.1, 0.0]}]
        ),
        meta={"renderer": "test"},
    )


def test_scan_draws_no_bars_when_stdout_is_not_a_terminal(tmp_path, monkeypatch, capfd):
    """`tabletop scan > log`: the scan reports progress hundreds of times; the log gets one
    summary line, no bar updates. (The scan itself is stubbed: a real one takes a minute.)"""
    rec = _tiny_recording()

    def fake_run_scan(spec, config, progress=None):
        for i in range(1, 501):
            progress(i, 500)
        return rec, ScanStats(frames=len(rec), simulated_s=0.1, wall_s=0.5, render_s=0.2, ik_s=0)

    monkeypatch.setattr("tabletop.sim.scan.run_scan", fake_run_scan)
    out_dir = tmp_path / "rec"
    assert main(["scan", "--episodes", "0", "--out", str(out_dir)]) == 0
    out, err = capfd.readouterr()
    for text in (out, err):
        assert "\r" not in text and "%|" not in text and "it/s" not in text
    assert "scan default: 500 frames in" in err
    assert err.count("scan default") == 1
    assert "frames recorded:  3 at 320x240" in out and "dog@(0.40,0.10)" in out
    assert len(load_recording(out_dir)) == 3


def test_format_bank_table():
    bank = SoundBank.default()
    text = format_bank_table(bank)
    s = bank.summary()
    for cat in bank.categories:
        row = s["categories"][cat]
        assert any(
            line.split()[:3] == [cat, str(row["train"]), str(row["heldout"])]
            for line in text.splitlines()
        ), cat
    for lic in s["licences"]:
        assert lic in text
    assert f"{len(bank)} clips in {len(bank.categories)} categories" in text


def test_sounds_command(capsys):
    assert main(["sounds"]) == 0
    assert capsys.readouterr().out.strip() == format_bank_table(SoundBank.default())
    assert main(["sounds", "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == SoundBank.default().summary()


def test_scenes_command(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("default") and "objects:" in out
    assert main(["scenes", "default"]) == 0
    assert json.loads(capsys.readouterr().out)["scene"]["name"] == "default"
    assert main(["scenes", "no-such-scene"]) == 2
    assert "tabletop scenes: error:" in capsys.readouterr().err


def test_scan_refuses_an_output_that_is_not_a_recording_before_scanning(tmp_path, capsys):
    from tabletop.cli import main

    photos = tmp_path / "photos"
    photos.mkdir()
    (photos / "a.jpg").write_bytes(b"x")
    rc = main(["scan", "--out", str(photos), "--overwrite"])
    assert rc != 0 and "is not a recording" in capsys.readouterr().err
    assert (photos / "a.jpg").read_bytes() == b"x"
