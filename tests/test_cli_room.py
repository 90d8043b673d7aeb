"""Tests of tabletop.cli.room: ``tabletop rooms`` and a short ``tabletop scan-room``."""

from __future__ import annotations

import tomllib

from tabletop.cli import main
from tabletop.recording import load_recording
from tabletop.sim.room import RoomSpec, generate_room, load_room_spec


def test_rooms_lists_prints_and_generates(capsys):
    assert main(["rooms"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("default") and "dining_table (table)" in out
    assert main(["rooms", "default"]) == 0
    assert RoomSpec.from_dict(tomllib.loads(capsys.readouterr().out)) == load_room_spec("default")
    assert main(["rooms", "--generate", "4"]) == 0
    assert RoomSpec.from_dict(tomllib.loads(capsys.readouterr().out)) == generate_room(4)
    assert main(["rooms", "attic"]) == 2
    assert "no shipped room 'attic'; shipped: ['default']" in capsys.readouterr().err


def test_scan_room_writes_a_recording(tmp_path, capsys):
    out = tmp_path / "room"
    args = ["scan-room", "--tables", "work_table", "--rate", "10", "--episodes", "1"]
    assert main([*args, "--views", "1", "--no-look-around", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "0 collisions" in text and "sounds inserted:  1:" in text and "@work_table" in text
    rec = load_recording(out)
    assert rec.meta["robot"] == "mobile_base" and rec.joint_positions.shape[1] == 2
    assert main([*args, "--out", str(out)]) == 2  # exists: refused before any scan
    assert "pass overwrite=True" in capsys.readouterr().err
