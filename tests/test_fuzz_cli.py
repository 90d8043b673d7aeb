"""Fuzzing the command line's argument validation: a bad flag fails fast and says which.

``tabletop.cli.main`` runs in-process with generated values that are invalid for the flag they
are given to (numbers out of range, nan, inf, words, empty and unicode strings; paths that do
not exist, directories where a file is expected, files where a directory is, existing outputs):
each must end with exit status 2, a message on stderr naming the flag (or its field or the
value), no Python traceback, and nothing written.

No generated input is valid, so none starts real work; as a guard, the entry points of real
work (a scan, a map build, a training run, the arm benchmark) are replaced for the duration of a
call by a tripwire that fails the test if validation let an input through to them. Every call
runs inside a fresh temporary directory, which is also the working directory.

The runs are derandomized; :data:`EXAMPLES` holds the number of generated inputs per test.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tabletop.cli import main
from tabletop.mapping.encoders.registry import ENCODER_SETS

#: Generated inputs per test (Hypothesis ``max_examples``; derandomized).
EXAMPLES = {"numbers": 1200, "paths": 800}
#: Generated inputs of this file in all.
TOTAL_EXAMPLES = sum(EXAMPLES.values())

#: Where real work starts: none of these may be reached by an invalid flag.
HEAVY_WORK = (
    ("tabletop.sim.scan", "run_scan"),
    ("tabletop.mapping.avlmap", "AVLMap.build"),
    ("tabletop.train.audio", "train_audio"),
    ("tabletop.train.vision", "train_vision"),
    ("tabletop.arm.bench", "run_arm_benchmark"),
)


def _settings(name: str):
    return settings(
        max_examples=EXAMPLES[name],
        deadline=20_000,  # [ms]: the first `run reference` loads the text encoder
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow],
    )


class HeavyWorkStarted(BaseException):
    """Raised by a tripwire: an invalid input got through to real work (a BaseException, so
    that the command's own error handling cannot swallow it)."""


def _tripwire(name: str):
    def tripped(*args, **kwargs):
        raise HeavyWorkStarted(f"{name} started: the flag was not validated first")

    return tripped


def run_cli(argv: list[str]) -> tuple[int, str, list[str]]:
    """Run ``tabletop`` with ``argv`` (``TMP`` in an argument: the temporary directory, which
    holds ``adir/`` (a directory) and ``afile.npz``/``afile.json`` (files that are not
    tabletop outputs)); return the exit status, stdout + stderr, and what the call left behind
    in the temporary directory besides those."""
    out = io.StringIO()
    with (
        tempfile.TemporaryDirectory() as d,
        pytest.MonkeyPatch.context() as mp,
        contextlib.chdir(d),
    ):
        for module, attr in HEAVY_WORK:
            owner = importlib.import_module(module)
            *path, name = attr.split(".")
            for p in path:
                owner = getattr(owner, p)
            mp.setattr(owner, name, _tripwire(f"{module}.{attr}"))
        root = Path(d)
        (root / "adir").mkdir()
        (root / "afile.npz").write_text("not a map")
        (root / "afile.json").write_text("{}")
        before = {p for p in root.rglob("*")}
        argv = [a.replace("TMP", d) for a in argv]
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
                status = main(argv)
        except SystemExit as e:  # argparse refuses a value with exit status 2
            status = e.code
        left = sorted(str(p.relative_to(root)) for p in set(root.rglob("*")) - before)
    return status, out.getvalue(), left


def assert_fails_fast(argv: list[str], names: tuple[str, ...]) -> None:
    status, text, left = run_cli(argv)
    assert "Traceback" not in text, text
    assert status == 2, (argv, status, text[-500:])
    assert any(n in text for n in names), (names, text[-500:])
    assert left == [], f"{argv} left {left} behind"


# ---------------------------------------------------------------------- values
def _parses(s: str) -> bool:
    for kind in (int, float):
        try:
            kind(s)
        except ValueError:
            continue
        return True
    return False


# words, empty and unicode strings, control characters: nothing a number parser takes
words = st.text(max_size=12).filter(lambda s: not _parses(s))
nan_inf = st.sampled_from(("nan", "NaN", "-nan", "inf", "-inf", "Infinity", "1e999", "-1e999"))
negative_floats = st.floats(max_value=-1e-9, allow_nan=False, allow_infinity=False).map(repr)
negative_ints = st.integers(max_value=-1).map(str)
non_ints = st.one_of(words, nan_inf, st.floats(allow_nan=False).map(repr).filter(
    lambda s: not _parses_int(s)
))  # fmt: skip


def _parses_int(s: str) -> bool:
    try:
        int(s)
    except ValueError:
        return False
    return True


def _not_a_fraction(s: str) -> bool:  # valid: a finite number in [0, 1)
    try:
        v = float(s)
    except ValueError:
        return True
    return not 0.0 <= v < 1.0


fractions_out_of_range = st.one_of(
    words, nan_inf, negative_floats, st.floats(min_value=1.0).map(repr)
).filter(_not_a_fraction)

SCAN = ["scan", "--out", "TMP/rec"]
RUN = ["run", "reference", "go to the mug", "--dry-run", "--embodiment", "point"]

# (command before the flag, the flag, invalid values, words its message may name it by)
NUMBER_FLAGS = [
    (SCAN, "--width", st.one_of(non_ints, st.integers(max_value=319).map(str)),
     ("--width", "width", "320x240")),
    (SCAN, "--height", st.one_of(non_ints, st.integers(max_value=239).map(str)),
     ("--height", "height", "320x240")),
    (SCAN, "--pose-noise", st.one_of(words, nan_inf, negative_floats),
     ("--pose-noise", "pose_translation_m")),
    (SCAN, "--rot-noise", st.one_of(words, nan_inf, negative_floats),
     ("--rot-noise", "pose_rotation_rad")),
    (SCAN, "--depth-noise", st.one_of(words, nan_inf, negative_floats),
     ("--depth-noise", "depth_relative")),
    (SCAN, "--depth-dropout", fractions_out_of_range, ("--depth-dropout", "depth_dropout")),
    (SCAN, "--drop-frames", fractions_out_of_range, ("--drop-frames", "drop_frames")),
    (SCAN, "--noise-seed", st.one_of(non_ints, negative_ints), ("--noise-seed", "noise seed")),
    (SCAN, "--seed", st.one_of(non_ints, negative_ints), ("--seed", "seed")),
    (SCAN, "--episodes", st.one_of(non_ints, negative_ints), ("--episodes", "episodes")),
    (["eval-map"], "--seeds", st.one_of(non_ints, st.integers(max_value=0).map(str)),
     ("--seeds", "seeds")),
    (["eval-map"], "--speed", st.one_of(words, nan_inf, negative_floats, st.just("0")),
     ("--speed", "speed")),
    (["train", "audio"], "--steps", st.one_of(non_ints, st.integers(max_value=0).map(str)),
     ("--steps", "steps")),
    (["train", "audio"], "--threads", st.one_of(non_ints, st.integers(max_value=0).map(str)),
     ("--threads", "threads")),
    (["train", "audio"], "--max-minutes", st.text(max_size=8), ("--max-minutes",)),
    (["train", "vision"], "--device", st.sampled_from(("cuda", "gpu", "", "CPU", "cpu ")),
     ("--device",)),
    (["train", "audio"], "--device", words.filter(lambda s: s not in ("cpu", "cuda")),
     ("--device",)),
    (["bench"], "--arm-targets", non_ints, ("--arm-targets",)),
    (["build-map", "TMP/nonexistent", "--out", "TMP/m.npz"], "--pixel-step", non_ints,
     ("--pixel-step",)),
    (["build-map", "TMP/nonexistent", "--out", "TMP/m.npz"], "--voxel-size", words,
     ("--voxel-size",)),
    (["build-map", "TMP/nonexistent", "--out", "TMP/m.npz"], "--encoders",
     words.filter(lambda s: s.strip().lower() not in ENCODER_SETS), ("--encoders",)),
    (["calibrate", "--out", "TMP/c.json"], "--keep-prior",
     words.filter(lambda s: s.strip(", ") != ""), ("--keep-prior",)),
    (RUN, "--timeout", st.one_of(words, st.sampled_from(("nan", "-nan", "0", "-0.0")),
     negative_floats), ("--timeout", "timeout_s")),
    (RUN, "--embodiment", words.filter(lambda s: s not in ("arm", "base", "point")),
     ("--embodiment",)),
    (["parse", "go to the mug"], "--backend", words.filter(lambda s: s not in ("offline", "llm")),
     ("--backend",)),
]  # fmt: skip


@st.composite
def bad_number_flags(draw):
    command, flag, values, names = draw(st.sampled_from(NUMBER_FLAGS))
    return [*command, f"{flag}={draw(values)}"], names


@_settings("numbers")
@given(case=bad_number_flags())
def test_invalid_flag_values_fail_fast_naming_the_flag(case):
    argv, names = case
    assert_fails_fast(argv, names)


# ---------------------------------------------------------------------- paths
# a name under the temporary directory: unicode, spaces and dots included; never created
names = st.text(
    alphabet=st.characters(codec="utf-8", exclude_characters="/\x00"), min_size=1, max_size=16
).filter(lambda s: s not in (".", ".."))
missing = names.map(lambda n: f"TMP/missing-{n}")
missing_npz = names.map(lambda n: f"TMP/missing-{n}.npz")
# something that exists and is not what the flag wants
ADIR, AFILE_NPZ, AFILE_JSON = "TMP/adir", "TMP/afile.npz", "TMP/afile.json"

PATH_CASES = [
    # (argv with PATH where the path goes, paths to put there)
    (["scan", "--out", "PATH"], st.sampled_from((ADIR, AFILE_NPZ, AFILE_JSON, "TMP", ""))),
    (["scan", "--out", "PATH", "--overwrite"], st.sampled_from((ADIR, AFILE_NPZ, "TMP"))),
    (["scan", "--out", "TMP/rec", "--scene", "PATH"],  # ('{}' is a scene of defaults)
     st.one_of(missing, missing.map(lambda p: p + ".toml"), st.sampled_from((ADIR, AFILE_NPZ)))),
    (["build-map", "PATH", "--out", "TMP/m.npz"],
     st.one_of(missing, st.sampled_from((ADIR, AFILE_NPZ, AFILE_JSON)))),
    (["build-map", "TMP/nonexistent", "--out", "PATH"],
     st.one_of(missing, st.sampled_from((ADIR, AFILE_NPZ, AFILE_JSON, "TMP")))),
    (["query", "PATH", "--obj", "mug"],
     st.one_of(missing_npz, st.sampled_from((ADIR, AFILE_NPZ, AFILE_JSON)))),
    (["query", "PATH", "--obj", "mug", "--encoders", "default"],
     st.one_of(missing_npz, st.sampled_from((ADIR, AFILE_NPZ)))),
    (["eval", "PATH", "--out", "TMP/o", "--cache-dir", "TMP/c"],
     st.one_of(missing, missing.map(lambda p: p + ".toml"), st.sampled_from((ADIR, AFILE_JSON)))),
    (["calibrate", "--out", "PATH"], st.sampled_from((ADIR, AFILE_JSON, AFILE_NPZ, "TMP"))),
    (["scenes", "PATH"], st.one_of(missing, st.sampled_from((ADIR, AFILE_NPZ)))),
    (["sounds", "--esc50", "PATH"], st.one_of(missing, st.sampled_from((ADIR, AFILE_JSON)))),
    (["run", "PATH", "go to the mug", "--dry-run"],
     st.one_of(missing_npz, st.sampled_from((ADIR, AFILE_NPZ)))),
    (["parse", "go to the mug", "--backend", "llm", "--llm-config", "PATH"],
     st.one_of(missing, st.sampled_from((ADIR,)))),
    (["parse", "--suite", "--suite-file", "PATH"],
     st.one_of(missing, st.sampled_from((ADIR, AFILE_JSON)))),
]  # fmt: skip


@st.composite
def bad_paths(draw):
    argv, paths = draw(st.sampled_from(PATH_CASES))
    path = draw(paths)
    return [path if a == "PATH" else a for a in argv], path


@_settings("paths")
@given(case=bad_paths())
def test_paths_that_are_missing_or_of_the_wrong_kind_fail_fast(case):
    argv, path = case
    status, text, left = run_cli(argv)
    assert "Traceback" not in text, text
    assert status == 2, (argv, status, text[-500:])
    name = Path(path.replace("TMP/", "")).name  # the message names the path it refuses,
    shown = (name, repr(name)[1:-1])  # as it is or escaped
    assert any(s in text for s in shown) or path in ("", "TMP"), (argv, text[-500:])
    assert left == [], f"{argv} left {left} behind"


# ---------------------------------------------------------------------- late validation
# Inputs the CLI once checked only after real work had started (or not at all): each now fails
# where the flag enters, before any scan, map or training.
CHECKED_BEFORE_WORK = [
    # (argv, words the message names the flag and its value by)
    (["eval", "default", "--out", "TMP/o", "--cache-dir", AFILE_JSON],
     ("--cache-dir", "afile.json", "directory")),
    (["eval", "default", "--out", AFILE_JSON, "--cache-dir", "TMP/c"],
     ("--out", "afile.json", "directory")),
    (["eval", "default", "--out", "TMP/afile.json/o", "--cache-dir", "TMP/c"],
     ("--out", "afile.json", "directory")),
    (["eval", "default", "--out", "TMP/o", "--cache-dir", "TMP/c", "--map-set", "voxel_size=nan"],
     ("--map-set", "voxel_size", "nan")),
    (["calibrate", "--encoders", "nope", "--out", "TMP/c.json"],
     ("--encoders", "'nope'", "oracle", "default")),
    (["calibrate", "--scenes", "-1", "--out", "TMP/c.json"], ("--scenes", "-1", "1..")),
    (["calibrate", "--scenes", "0", "--out", "TMP/c.json"], ("--scenes", "0", "1..")),
    (["calibrate", "--scenes", "99", "--out", "TMP/c.json"], ("--scenes", "99", "1..")),
    (["calibrate", "--cache-dir", AFILE_JSON, "--out", "TMP/c.json"],
     ("--cache-dir", "afile.json", "directory")),
    # only white space and commas: names no modality (a generated case once started a scan)
    (["calibrate", "--keep-prior", " ,\t", "--out", "TMP/c.json"],
     ("--keep-prior", "object", "sound")),
    (["scan", "--out", "TMP/rec", "--width", "100000000"],
     ("--width", "100000000", "at most 1920x1440")),
    (["scan", "--out", "TMP/rec", "--height", "100000000"],
     ("--height", "100000000", "at most 1920x1440")),
    (["bench", "--arm-targets", "-1"], ("--arm-targets", "-1", ">= 1")),
    (["bench", "--arm-targets", "0"], ("--arm-targets", "0", ">= 1")),
    (["bench", "--arm-targets", "1000000000000"],
     ("--arm-targets", "1000000000000", "at most 10000")),
    (["train", "vision", "--max-minutes", "-1"], ("--max-minutes", "-1", "> 0")),
    (["train", "vision", "--max-minutes", "0"], ("--max-minutes", "0", "> 0")),
    (["train", "vision", "--max-minutes", "nan"], ("--max-minutes", "nan", "> 0")),
    (["train", "audio", "--out", ADIR], ("--out", "adir", "directory")),
    (["train", "audio", "--backbone", "small", "--out", AFILE_NPZ],
     ("--out", "afile.npz", "not a torch checkpoint")),
    (["train", "audio", "--out", AFILE_NPZ], ("--out", "afile.npz", "not a YAMNet head")),
    (["train", "vision", "--out", "TMP/afile.npz/w.pt"], ("--out", "afile.npz", "directory")),
]  # fmt: skip


@pytest.mark.parametrize(
    "argv, words", CHECKED_BEFORE_WORK, ids=[f"c{i}" for i in range(len(CHECKED_BEFORE_WORK))]
)
def test_flags_once_checked_late_fail_before_any_work(argv, words):
    status, text, left = run_cli(argv)  # HeavyWorkStarted propagates: the test fails
    assert "Traceback" not in text, text
    assert status == 2, (argv, status, text[-500:])
    missing = [w for w in words if w not in text]
    assert not missing, (missing, text[-500:])
    assert left == [], f"{argv} left {left} behind"


def test_the_harness_sees_heavy_work_and_leftovers():
    """The checks above can fail: a valid command reaches the tripwire, and a valid cheap one
    passes the harness with status 0."""
    with pytest.raises(HeavyWorkStarted, match="run_scan"):
        run_cli(["scan", "--out", "TMP/rec"])
    status, text, left = run_cli(["scenes"])
    assert status == 0 and "default" in text and left == []
    assert TOTAL_EXAMPLES == sum(EXAMPLES.values()) >= 500


@pytest.mark.parametrize(
    "argv",
    [["eval-map", "--seeds", "0"], ["demo", "--encoders", "foo"], ["demo", "--encoders", ","]],
)
def test_a_refused_flag_is_the_first_thing_said(argv):
    # the command's banner had been printed before the refusal, as if the run had started
    status, text, left = run_cli(argv)
    assert status == 2 and left == []
    assert text.strip().splitlines()[0].startswith(f"tabletop {argv[0]}: error"), text
