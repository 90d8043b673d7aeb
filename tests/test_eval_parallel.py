"""``tabletop eval --workers N`` and ``--ray ADDRESS`` give goal for goal what a serial run
gives (tabletop/parallel.py, tabletop/eval/compare.py).

Two tiny task files on the session's fast scan of the default scene (``helpers.fast_scan``,
put in the cache: conftest runs this file with the others that read it), each with its own
map (the oracle encoders): a serial run; the same in two worker processes, which build the
maps again; then as Ray tasks on a local cluster that the fixture starts (``ray start --head``
on 127.0.0.1 with two CPUs) and stops, over the serial run's cache (skipped where Ray, the
optional extra ``ray``, is not installed).
"""

import importlib.util
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import tabletop
from tabletop.cli import main
from tabletop.errors import ConfigError
from tabletop.eval.compare import IGNORED, compare_results, goal_count, load_results
from tabletop.parallel import RAY_LOOPBACK_ENV, Backend, UnitError, limit_threads, run_units

TASK = """format = "tabletop-tasks"
version = 1
name = "{name}"

[scene]
name = "default"

[scan]
{scan}

[map]
frame_step = {frame_step}

[[goals]]
id = "{obj}"
type = "object"
text = "the {words}"
query = {{ obj = "{words}" }}
truth = {{ object = "{obj}" }}

[[goals]]
id = "absent-giraffe"
type = "absent"
text = "the giraffe"
query = {{ obj = "the giraffe" }}
truth = {{ absent = true }}
"""
#: the map settings of every run: no table registration (a tiny map, built fast)
FAST = ["--map-set", "registration.enabled=false"]


def _eval(files, out: Path, cache: Path, *flags) -> dict:
    argv = ["eval", *map(str, files), "--out", str(out), "--cache-dir", str(cache)]
    assert main([*argv, *FAST, *flags]) == 0
    return load_results(out)


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """(task files, the serial run's results, its cache)."""
    from helpers import FAST_SCAN, fast_scan

    from tabletop.eval.harness import recording_key
    from tabletop.recording import save_recording
    from tabletop.sim.scene import load_scene_spec

    tmp = tmp_path_factory.mktemp("parallel")
    scan = "\n".join(f"{k} = {json.dumps(v)}" for k, v in FAST_SCAN.items())
    files = []
    for name, frame_step, obj, words in (
        ("tiny-a", 16, "red_mug", "red mug"),
        ("tiny-b", 20, "soccer_ball", "white soccer ball"),
    ):
        files.append(tmp / f"{name}.toml")
        text = TASK.format(name=name, scan=scan, frame_step=frame_step, obj=obj, words=words)
        files[-1].write_text(text)
    cache = tmp / "cache-serial"
    key = recording_key(load_scene_spec("default"), dict(FAST_SCAN))
    save_recording(fast_scan()[0], cache / f"rec-default-{key}")  # what a scan would cache
    return files, _eval(files, tmp / "serial", cache), cache


def _same(a: dict, b: dict) -> None:
    assert compare_results(a, b) == []
    assert goal_count(a) == goal_count(b) == 4
    ids = [g["goal_id"] for r in b["rows"] for t in r["tasks"] for g in t["goals"]]
    assert ids == ["red_mug", "absent-giraffe", "soccer_ball", "absent-giraffe"]  # serial order
    assert b["by_type"]["object"]["success_rate"] == 1.0 and b["contacts"] == 0


@pytest.mark.slow  # a serial eval and a parallel one of the same tasks: two minutes of CPU
def test_two_workers_give_the_serial_results(serial, tmp_path, capfd):
    files, first, cache = serial
    (rec,) = cache.glob("rec-*")  # the recording; the workers build the maps
    shutil.copytree(rec, tmp_path / "cache" / rec.name)
    capfd.readouterr()
    again = _eval(files, tmp_path / "out", tmp_path / "cache", "--workers", "2")
    _same(first, again)
    assert [t["map_s"] > 0 for t in again["rows"][0]["tasks"]] == [True, True]
    err = capfd.readouterr().err  # progress: a line per unit of work as it finishes
    assert "/2] oracle x tiny-a: 2/2 goals succeeded" in err
    assert "units: 2 units in" in err
    assert main(["eval-compare", str(tmp_path / "out"), str(files[0].parent / "serial")]) == 0
    assert "the same: 4 goals in 1 rows" in capfd.readouterr().out


# ---------------------------------------------------------------------------- Ray
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def ray_cluster():
    """The address of a Ray cluster on 127.0.0.1 (two CPUs), started for these tests in a
    process group of their own and stopped with it."""
    if importlib.util.find_spec("ray") is None:  # not imported here: import_ray does that
        pytest.skip("Ray is not installed (the optional extra: pip install -e '.[ray]')")
    exe = Path(sys.executable).with_name("ray")
    if not exe.is_file():
        pytest.skip(f"no `ray` command beside {sys.executable}")
    tmp = Path(tempfile.mkdtemp(prefix="ray-", dir="/tmp"))  # short: Ray's socket paths
    port = _free_port()
    root = str(Path(tabletop.__file__).parents[1])  # the workers import this tabletop
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p),
        "RAY_USAGE_STATS_ENABLED": "0",
        RAY_LOOPBACK_ENV: "0",  # every address on loopback
    }
    cmd = [
        str(exe), "start", "--head", "--block", "--node-ip-address", "127.0.0.1",
        "--port", str(port), "--num-cpus", "2", "--temp-dir", str(tmp),
        "--include-dashboard", "false", "--disable-usage-stats",
        "--object-store-memory", str(200 * 2**20),
    ]  # fmt: skip
    proc = subprocess.Popen(
        cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,
    )  # fmt: skip
    lines: list[str] = []
    up = threading.Event()

    def read():
        for line in proc.stdout:
            lines.append(line)
            if "Ray runtime started" in line:
                up.set()

    threading.Thread(target=read, daemon=True).start()
    try:
        if not up.wait(120) or proc.poll() is not None:
            raise RuntimeError("ray start did not come up:\n" + "".join(lines[-30:]))
        yield f"127.0.0.1:{port}"
    finally:
        _stop_cluster(proc, tmp)


def _stop_cluster(proc: subprocess.Popen, tmp: Path) -> None:
    """Stop the processes this fixture started: `ray start --block` ends its own on SIGTERM;
    what is left of its process group, and any process of this cluster's temporary directory,
    is killed by its id."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            pass
    pids = set()
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            cmdline = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            same_group = os.getpgid(int(d.name)) == proc.pid
        except (OSError, ProcessLookupError):
            continue
        if same_group or str(tmp) in cmdline:
            pids.add(int(d.name))
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    deadline = time.monotonic() + 10
    while pids and time.monotonic() < deadline:
        pids = {p for p in pids if Path(f"/proc/{p}").exists()}
        time.sleep(0.1)
    shutil.rmtree(tmp, ignore_errors=True)


@pytest.mark.slow  # a local Ray cluster running the serial eval's tasks
def test_ray_tasks_give_the_serial_results(serial, ray_cluster, tmp_path, capfd):
    files, first, cache = serial
    shutil.copytree(cache, tmp_path / "cache")  # the recording and the maps: the goals run
    capfd.readouterr()
    again = _eval(files, tmp_path / "out", tmp_path / "cache", "--ray", ray_cluster)
    _same(first, again)
    err = capfd.readouterr().err
    assert "oracle x tiny-b: 2/2 goals succeeded" in err and "units: 2 units in" in err


def test_ray_refuses_an_address_without_a_cluster():
    if importlib.util.find_spec("ray") is None:
        pytest.skip("Ray is not installed (the optional extra: pip install -e '.[ray]')")
    t0 = time.monotonic()
    with pytest.raises(ConfigError, match="no Ray cluster to connect to"):
        run_units(int, [("1",)], Backend(ray=f"127.0.0.1:{_free_port()}"))
    assert time.monotonic() - t0 < 15  # at once, not after Ray's minutes of retries


# ---------------------------------------------------------------------------- the backend
def test_units_come_back_in_their_order_and_errors_name_the_unit():
    from parallel_helpers import boom, threads

    done = []
    out = run_units(
        boom, [(1,), (4,), (5,)], Backend(workers=2), on_done=lambda i, r, s: done.append(i)
    )
    assert out == [10, 40, 50] and sorted(done) == [0, 1, 2]
    with pytest.raises(ConfigError, match="bad value 3") as e:
        run_units(boom, [(1,), (3,)], Backend(workers=2), labels=["one", "three"])
    assert any("a worker process (three)" in n for n in getattr(e.value, "__notes__", []))
    # an error that does not survive pickling comes back with its type and message; each
    # worker has one math thread, whatever this process has
    with pytest.raises(UnitError, match=r"GoalNotFound: obj='x': not found \(nothing there\)"):
        run_units(boom, [(2,)], Backend(workers=1))
    assert run_units(threads, [()], Backend(workers=1)) == [("1", 1)]
    assert run_units(boom, [(1,), (4,)]) == [10, 40]  # serial: in this process


def test_bad_backends_are_refused_before_any_work(tmp_path, capfd, monkeypatch):
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ConfigError, match="workers must be a whole number >= 1"):
            Backend(workers=bad)
    with pytest.raises(ConfigError, match="ray must be a cluster address"):
        Backend(ray=" ")
    cache = tmp_path / "cache"
    assert main(["eval", "demo", "--cache-dir", str(cache), "--workers", "0"]) == 2
    assert "workers must be a whole number >= 1" in capfd.readouterr().err
    monkeypatch.setitem(sys.modules, "ray", None)  # as if the extra were not installed
    assert main(["eval", "demo", "--cache-dir", str(cache), "--ray", "auto"]) == 2
    assert "pip install -e '.[ray]'" in capfd.readouterr().err
    assert not cache.exists()


def test_limit_threads_sets_the_environment_and_torch(monkeypatch):
    import torch

    before = torch.get_num_threads()
    for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        monkeypatch.delenv(k, raising=False)
    try:
        limit_threads(1)
        assert os.environ["OMP_NUM_THREADS"] == "1" and torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(before)


# ---------------------------------------------------------------------------- the comparison
def test_the_comparison_ignores_timings_and_names_every_other_difference(tmp_path, capfd):
    goal = {"goal_id": "g", "tcp": [0.1, 0.2, 0.3], "success": True, "time_s": 1.0}
    a = {
        "wall_s": 10.0, "report": "a/report.md", "by_type": {"object": {"time_per_goal_s": 1.0}},
        "rows": [{"tasks": [{"scan_s": 3.0, "map_s": 2.0, "cached": False, "goals": [goal]}]}],
    }  # fmt: skip
    b = json.loads(json.dumps(a))
    t = b["rows"][0]["tasks"][0]
    t["scan_s"], t["cached"], t["goals"][0]["time_s"], b["report"] = 0.0, True, 9.0, "b/r.md"
    b["by_type"]["object"]["time_per_goal_s"] = 3.0
    assert compare_results(a, b) == [] and goal_count(a) == 1
    assert {"time_s", "planning_s", "wall_s", "cached"} <= IGNORED
    c = json.loads(json.dumps(a))
    c["rows"][0]["tasks"][0]["goals"][0]["tcp"][2] = 0.31
    c["rows"][0]["tasks"][0]["goals"][0]["success"] = False
    c["extra"] = 1
    assert compare_results(a, c) == [
        "extra: only in the second",
        "rows[0].tasks[0].goals[0].success: true != false",
        "rows[0].tasks[0].goals[0].tcp[2]: 0.3 != 0.31",
    ]
    d = json.loads(json.dumps(a))
    d["rows"][0]["tasks"][0]["goals"].append(goal)
    assert compare_results(a, d) == ["rows[0].tasks[0].goals: 1 items != 2 items"]
    assert compare_results({"x": 1, "y": float("nan")}, {"x": 1.0, "y": float("nan")}) == []
    # the command: 0 when the same, 1 with the differences
    (tmp_path / "a.json").write_text(json.dumps(a))
    (tmp_path / "c").mkdir()
    (tmp_path / "c" / "results.json").write_text(json.dumps(c))
    assert main(["eval-compare", str(tmp_path / "a.json"), str(tmp_path / "a.json")]) == 0
    assert main(["eval-compare", str(tmp_path / "a.json"), str(tmp_path / "c")]) == 1
    out = capfd.readouterr().out
    assert "tcp[2]: 0.3 != 0.31" in out and "3 differences" in out
    assert main(["eval-compare", str(tmp_path / "a.json"), str(tmp_path / "nope")]) == 2


def test_rendered_training_data_is_the_same_from_workers():
    from tabletop.train.vision import render_dataset

    seeds = [9_000_321, 9_000_322]  # a slice of the layouts each
    a = render_dataset(seeds, views=1, heldout=False, seed=0, lit=False)
    b = render_dataset(seeds, views=1, heldout=False, seed=0, lit=False, backend=Backend(workers=2))
    assert a[0].shape == b[0].shape == (2, 240, 320, 3)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
