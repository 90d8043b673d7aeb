"""Tests of tabletop.cli: the parser built from the command groups, the progress display, the
default output paths, and the layer rule (nothing in the library imports the CLI)."""

from __future__ import annotations

import io
import os
import re
import shlex
from pathlib import Path

import pytest

import tabletop
from tabletop.cli import build_parser, main
from tabletop.cli.progress import LIBRARY_BAR_SWITCHES, ProgressBars, interactive, no_library_bars

PACKAGE = Path(tabletop.__file__).resolve().parent
README = PACKAGE.parent / "README.md"


# --------------------------------------------------------------------------- the parser
def _readme_commands() -> list[list[str]]:
    """The argument lists of README.md's "Commands" block (comments and [...] dropped)."""
    text = README.read_text(encoding="utf-8")
    block = text.split("## Commands", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    out = []
    for line in block.splitlines():
        line = re.sub(r"\s+#.*$", "", line).strip()
        if line.startswith("tabletop "):
            line = re.sub(r"\[[^\]]*\]", "", line).split("|")[0]
            out.append(shlex.split(line)[1:])
    return out


def test_every_readme_command_parses():
    commands = _readme_commands()
    assert len({c[0] for c in commands}) >= 14
    parser = build_parser()
    for argv in commands:
        args = parser.parse_args(argv)
        assert callable(args.func), argv


def test_every_command_has_help(capsys):
    names = {c[0] for c in _readme_commands()}
    for name in sorted(names):
        with pytest.raises(SystemExit) as e:
            main([name, "--help"])
        assert e.value.code == 0, name
        assert f"usage: tabletop {name}" in capsys.readouterr().out


def test_an_unknown_command_names_the_valid_ones(capsys):
    with pytest.raises(SystemExit) as e:
        main(["scna"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'scna'" in err and "'scan'" in err


def test_a_misspelt_option_is_named_with_the_nearest_valid_one(capsys):
    # "tabletop --hlep" said only that a COMMAND is required
    cases = [
        (["--hlep"], "'--hlep' (did you mean --help?)", "'tabletop'"),
        (["--verbsoe", "scenes"], "'--verbsoe' (did you mean --verbose?)", "'tabletop'"),
        (["run", "--hlep"], "'--hlep' (did you mean --help?)", "'tabletop run'"),
        (
            ["run", "map.npz", "--dyr-run"],
            "'--dyr-run' (did you mean --dry-run?)",
            "'tabletop run'",
        ),
        (
            ["query", "m.npz", "mug", "--ouput=x"],
            "'--ouput' (did you mean --out?)",
            "'tabletop query'",
        ),
    ]
    for argv, needle, where in cases:
        with pytest.raises(SystemExit) as e:
            main(argv)
        err = capsys.readouterr().err
        assert e.value.code == 2, argv
        assert f"unknown option {needle}" in err and f"the options of {where}" in err, err
    # abbreviations, negative numbers and "--" still parse
    parser = build_parser()
    assert parser.parse_args(["--verb", "scenes"]).verbose
    assert parser.parse_args(["-v", "scenes"]).verbose
    args = parser.parse_args(["run", "m.npz", "go to the mug", "--dry", "--timeout", "-1"])
    assert args.dry_run and args.timeout == -1.0
    assert (
        parser.parse_args(["run", "m.npz", "--", "-go to the mug"]).instruction == "-go to the mug"
    )


def test_an_option_of_one_value_given_twice_is_refused(capsys):
    # "scan --scene A --scene B" scanned B without a word about A
    cases = [
        (["scan", "--scene", "aa", "--scene", "bb"], "--scene", "'tabletop scan'"),
        (["query", "m.npz", "--obj", "x", "--obj=y"], "--obj", "'tabletop query'"),
        (["query", "m.npz", "--ob", "x", "--obj", "y"], "--obj", "'tabletop query'"),
        (["run", "m.npz", "go", "--dry-run", "--dry"], "--dry-run", "'tabletop run'"),
        (["-v", "--verbose", "scenes"], "--verbose", "'tabletop'"),
    ]
    for argv, option, _where in cases:
        with pytest.raises(SystemExit) as e:
            main(argv)
        err = capsys.readouterr().err
        assert e.value.code == 2, argv
        assert f"option {option} is given more than once" in err and "give it once" in err, err
    # a value that looks like the option's name is a value, and a command's options are its own
    parser = build_parser()
    args = parser.parse_args(["-v", "run", "m.npz", "go", "--timeout", "-1", "--dry-run"])
    assert args.verbose and args.timeout == -1.0 and args.dry_run


def test_nothing_in_the_library_imports_the_cli():
    pattern = re.compile(r"^\s*(from|import)\s+tabletop\.cli\b|from tabletop import cli", re.M)
    offenders = [
        str(p.relative_to(PACKAGE))
        for p in PACKAGE.rglob("*.py")
        if "cli" not in p.relative_to(PACKAGE).parts[:1] and pattern.search(p.read_text())
    ]
    assert offenders == []
    assert not (PACKAGE / "eval" / "cli.py").exists()
    assert not (PACKAGE / "language" / "cli.py").exists()


# --------------------------------------------------------------------------- progress
def test_bars_are_drawn_when_asked():
    f = io.StringIO()
    with ProgressBars(bars=True, file=f) as bars:
        for i in range(1, 6):
            bars("scan default", i, 5)
        for i in range(1, 3):
            bars("goals demo", i, 2)
    text = f.getvalue()
    assert "\r" in text and "%|" in text
    assert "scan default" in text and "5/5" in text and "goal" in text


def test_without_bars_one_line_per_stage():
    f = io.StringIO()
    bars = ProgressBars(bars=False, file=f)
    stage = bars.stage("map demo")
    for i in range(1, 101):
        stage(i, 100)
    bars("goals demo", 1, 3)  # a new stage ends the previous one
    bars.close()
    bars.close()  # closing twice writes nothing more
    lines = f.getvalue().splitlines()
    assert len(lines) == 2 and "\r" not in f.getvalue()
    assert re.fullmatch(r"map demo: 100 frames in \d+\.\d s", lines[0]), lines[0]
    assert re.fullmatch(r"goals demo: 1/3 goals in \d+\.\d s", lines[1]), lines[1]


def test_bars_only_on_a_terminal(monkeypatch):
    class Tty(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr("sys.stdout", io.StringIO())
    monkeypatch.setattr("sys.stderr", Tty())
    assert not interactive() and not ProgressBars().bars  # `tabletop demo > log`
    monkeypatch.setattr("sys.stdout", Tty())
    assert interactive() and ProgressBars().bars


def test_library_bars_are_switched_off_within_the_block_only(monkeypatch):
    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    monkeypatch.setenv("HF_HUB_DISABLE_PROGRESS_BARS", "0")  # the user's choice is kept
    with no_library_bars():
        assert os.environ["TQDM_DISABLE"] == LIBRARY_BAR_SWITCHES["TQDM_DISABLE"]
        assert os.environ["HF_HUB_DISABLE_PROGRESS_BARS"] == "0"
    assert "TQDM_DISABLE" not in os.environ
    assert os.environ["HF_HUB_DISABLE_PROGRESS_BARS"] == "0"


# --------------------------------------------------------------------------- default outputs
def test_train_writes_under_the_working_directory_by_default(tmp_path, monkeypatch, capsys):
    import tabletop.train.audio as train_audio
    import tabletop.train.audio_head as train_head

    seen = []
    monkeypatch.setattr(train_audio, "train_audio", lambda cfg: seen.append(cfg.out) or cfg.out)
    monkeypatch.setattr(train_head, "train_audio_head", lambda cfg: seen.append(cfg.out) or cfg.out)
    monkeypatch.chdir(tmp_path)
    assert main(["train", "audio"]) == 0
    assert main(["train", "audio", "--backbone", "effnet-lite0"]) == 0
    assert main(["train", "audio", "--backbone", "small", "--out", "elsewhere/a.pt"]) == 0
    assert seen == [
        Path("out/weights/audio_yamnet_head.npz"),
        Path("out/weights/audio.pt"),
        Path("elsewhere/a.pt"),
    ]
    assert "weights written: out/weights/audio_yamnet_head.npz" in capsys.readouterr().out
    assert main(["train", "audio", "--steps", "5"]) != 0
    assert "--steps: not for the YAMNet head" in capsys.readouterr().err
    assert main(["train", "vision", "--backbone", "yamnet"]) != 0
    assert "yamnet: for audio only" in capsys.readouterr().err


def test_calibrate_writes_under_the_working_directory_by_default(tmp_path, monkeypatch):
    import tabletop.eval.calibration as fitting
    from tabletop.mapping.calibration import CALIBRATION_DIR, Calibration

    shipped = CALIBRATION_DIR / "default.json"
    before = shipped.stat().st_mtime_ns if shipped.exists() else None
    monkeypatch.setattr(
        fitting,
        "run_calibration",
        lambda encoders, seeds, progress=None, cache_dir=None: Calibration(encoders, {}, {}),
    )
    monkeypatch.chdir(tmp_path)
    assert main(["calibrate", "--scenes", "1"]) == 0
    assert (tmp_path / "out" / "calibration" / "default.json").is_file()
    assert main(["calibrate", "--scenes", "1", "--out", "c.json"]) == 0
    assert (tmp_path / "c.json").is_file()
    assert (shipped.stat().st_mtime_ns if shipped.exists() else None) == before


def test_no_command_writes_into_the_package_by_default():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, p in sub.choices.items():
        for a in p._actions:
            if a.dest in ("out", "cache_dir") and isinstance(a.default, str):
                assert not Path(a.default).is_absolute(), (name, a.default)
                assert "tabletop/data" not in a.default, (name, a.default)
