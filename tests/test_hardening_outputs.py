"""Hardening of the commands' map files: ``--out`` and ``--overwrite`` replace only what this
package wrote (a map, a calibration), refuse anything else before any work, and never rename a
suffix silently; ``query --encoders`` refuses a map built with another encoder set."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tabletop.cli import main
from tabletop.errors import ConfigError
from tabletop.mapping.persistence import (
    MAP_FORMAT,
    MapFormatError,
    check_map_encoders,
    check_map_output,
)


def _fake_map_file(path):
    """A file with a map header (what check_map_output recognises; only the header is read)."""
    header = json.dumps({"format": MAP_FORMAT, "version": 4}).encode()
    np.savez(path, header=np.frombuffer(header, np.uint8))
    return path


def test_build_map_refuses_an_existing_file_without_overwrite_before_loading(tmp_path, capsys):
    photo = tmp_path / "holiday.npz"
    photo.write_bytes(b"my data")
    rc = main(["build-map", str(tmp_path / "no-recording"), "--out", str(photo)])
    err = capsys.readouterr().err
    assert rc == 2 and f"{photo} exists; pass --overwrite" in err
    assert "loading" not in err  # refused before the recording was read
    assert photo.read_bytes() == b"my data"


def test_build_map_overwrite_replaces_only_a_map(tmp_path, capsys):
    photo = tmp_path / "holiday.npz"
    photo.write_bytes(b"my data")
    rc = main(["build-map", str(tmp_path / "rec"), "--out", str(photo), "--overwrite"])
    assert rc == 2 and "is not a map" in capsys.readouterr().err
    assert photo.read_bytes() == b"my data"
    folder = tmp_path / "maps.npz"
    folder.mkdir()
    with pytest.raises(ConfigError, match="is a directory"):
        check_map_output(folder, overwrite=True)
    old = _fake_map_file(tmp_path / "old.npz")
    assert check_map_output(old, overwrite=True) == old


def test_build_map_never_renames_a_suffix(tmp_path, capsys):
    rc = main(["build-map", str(tmp_path / "rec"), "--out", str(tmp_path / "notes.map")])
    assert rc == 2 and "must end in .npz" in capsys.readouterr().err
    assert not (tmp_path / "notes.npz").exists()


def test_calibrate_refuses_an_output_that_is_not_a_calibration(tmp_path, monkeypatch, capsys):
    import tabletop.eval.calibration as fitting

    def no_work(*a, **k):
        raise AssertionError("calibrated before checking --out")

    monkeypatch.setattr(fitting, "run_calibration", no_work)
    notes = tmp_path / "notes.json"
    notes.write_text('{"mine": 1}')
    rc = main(["calibrate", "--scenes", "1", "--out", str(notes)])
    assert rc == 2 and "is not a calibration file" in capsys.readouterr().err
    assert notes.read_text() == '{"mine": 1}'


def test_query_refuses_a_map_of_another_encoder_set_before_loading_it(tmp_path, capsys):
    path = tmp_path / "cached.npz"
    header = {"format": MAP_FORMAT, "version": 4, "encoder_set": "default"}
    np.savez(path, header=np.frombuffer(json.dumps(header).encode(), np.uint8))
    rc = main(["query", str(path), "--obj", "mug", "--encoders", "oracle"])
    err = capsys.readouterr().err
    assert rc == 2
    assert f"{path} was built with the encoder set 'default', not 'oracle'" in err
    assert check_map_encoders(path, "default") == "default"
    notes = tmp_path / "notes.npz"
    notes.write_bytes(b"not a map")
    with pytest.raises(MapFormatError, match="is not a readable tabletop-avlmap file"):
        check_map_encoders(notes, "oracle")
