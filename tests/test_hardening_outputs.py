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


_SLOW_SAVE = r"""
import signal, sys, time
import numpy as np
# A shell that starts the tests in the background leaves SIGINT ignored in its children;
# a user's terminal does not: act as from a terminal.
signal.signal(signal.SIGINT, signal.default_int_handler)
from tabletop.atomic import exit_on_signals
from tabletop.recording import Recording, save_recording

n = 400
rng = np.random.default_rng(0)
rec = Recording(
    timestamps=np.arange(n) / 30.0,
    rgb=rng.integers(0, 256, (n, 240, 320, 3), dtype=np.uint8),
    depth=np.full((n, 240, 320), 0.5, np.float32),
    joint_positions=np.zeros((n, 7)),
    T_world_hand=np.tile(np.eye(4), (n, 1, 1)),
    K=np.array([[200.0, 0, 160], [0, 200.0, 120], [0, 0, 1]]),
    T_hand_cam=np.eye(4),
)
print("ready", flush=True)
with exit_on_signals():
    save_recording(rec, sys.argv[1], workers=1)
"""


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGINT"])
def test_a_killed_write_leaves_no_hidden_temporary_directory(tmp_path, sig):
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "rec"
    proc = subprocess.Popen(
        [sys.executable, "-c", _SLOW_SAVE, str(out)], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout.readline().strip() == "ready"
    deadline = time.monotonic() + 60
    while not any(p.name.startswith(".rec.") for p in tmp_path.iterdir()):
        assert time.monotonic() < deadline and proc.poll() is None, "the write never started"
        time.sleep(0.02)
    time.sleep(0.3)  # some frames are written
    proc.send_signal(getattr(signal, sig))
    rc = proc.wait(timeout=60)
    # SIGTERM: SystemExit(143); SIGINT: KeyboardInterrupt, which Python ends by the signal
    assert rc == (128 + signal.SIGTERM if sig == "SIGTERM" else -signal.SIGINT)
    assert list(tmp_path.iterdir()) == []  # neither the recording nor its temporary directory


def test_a_second_process_waits_for_the_first_to_leave_an_exclusive_block(tmp_path):
    """Two evals that need the same missing cache entry make it once: the second enters the
    block only when the first has left it (without the lock it would write in between)."""
    import subprocess
    import sys
    import time

    log, ready, target = tmp_path / "log", tmp_path / "ready", tmp_path / "cache" / "entry"
    code = (
        "import sys, time, pathlib\n"
        "from tabletop.atomic import exclusive\n"
        "log, ready, target, who, hold = sys.argv[1:6]\n"
        "with exclusive(target):\n"
        "    with open(log, 'a') as f: f.write(who + ' in\\n')\n"
        "    pathlib.Path(ready).touch()\n"
        "    time.sleep(float(hold))\n"
        "    with open(log, 'a') as f: f.write(who + ' out\\n')\n"
    )
    args = [str(log), str(ready), str(target)]
    first = subprocess.Popen([sys.executable, "-c", code, *args, "first", "1.5"])
    t0 = time.monotonic()
    while not ready.exists():
        assert time.monotonic() - t0 < 60 and first.poll() is None
        time.sleep(0.02)
    second = subprocess.Popen([sys.executable, "-c", code, *args, "second", "0"])
    assert first.wait(60) == 0 and second.wait(60) == 0
    assert log.read_text().split("\n")[:4] == ["first in", "first out", "second in", "second out"]


def test_ctrl_c_during_a_command_ends_it_with_a_line_not_a_traceback(tmp_path):
    """Ctrl-C while ``tabletop scan`` runs: exit status 130, one line saying it was interrupted,
    no traceback, and no recording left behind."""
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "rec"
    code = (
        "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
        "from tabletop.cli import main; sys.exit(main(['scan', '--out', sys.argv[1]]))"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code, str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    seen = []
    for line in proc.stderr:  # the simulator loaded or the scan's progress: it is under way
        seen.append(line)
        if "pybullet" in line or "frames" in line:
            break
        assert time.monotonic() < deadline, "the scan never started"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    err = "".join(seen) + err
    assert proc.returncode == 130, err[-500:]
    assert "tabletop scan: interrupted" in err and "Traceback" not in err
    assert not out.exists()
