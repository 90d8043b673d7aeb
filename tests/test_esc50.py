"""Tests of tabletop.sim.esc50: a local ESC-50-format data set as a sound bank."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from tabletop.audio import write_wav
from tabletop.errors import AssetError, ConfigError
from tabletop.sim.esc50 import ESC50_COLUMNS, load_esc50
from tabletop.sim.sound_bank import CAPTIONS

ESC_RATE = 44100


def _make_esc50(root: Path, rows: list[tuple[str, int, str, float]]) -> Path:
    """An ESC-50-format directory: one 1 s 44.1 kHz sine per row (filename, fold, cat, Hz)."""
    (root / "audio").mkdir(parents=True)
    (root / "meta").mkdir()
    t = np.arange(ESC_RATE) / ESC_RATE
    targets = {}
    with (root / "meta" / "esc50.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(ESC50_COLUMNS)
        for name, fold, cat, hz in rows:
            target = targets.setdefault(cat, len(targets))
            w.writerow([name, fold, target, cat, "False", name.split("-")[1], name.split("-")[2]])
            write_wav(root / "audio" / name, 0.5 * np.sin(2 * np.pi * hz * t), ESC_RATE)
    return root


@pytest.fixture
def esc50_dir(tmp_path) -> Path:
    rows = []
    for fold in range(1, 6):
        rows.append((f"{fold}-1000{fold}-A-0.wav", fold, "dog", 500.0))
        rows.append((f"{fold}-2000{fold}-A-1.wav", fold, "clock_alarm", 2000.0))
    return _make_esc50(tmp_path / "ESC-50-master", rows)


def test_load_esc50(esc50_dir):
    esc = load_esc50(esc50_dir)
    assert esc.categories == ["clock_alarm", "dog"]
    assert esc.sample_rate == 16000 and len(esc) == 10
    held = esc.clips(split="heldout")
    assert sorted(c.source_path for c in held) == ["5-10005-A-0.wav", "5-20005-A-1.wav"]
    assert esc.caption("clock_alarm") == CAPTIONS["clock_alarm"]
    clip = esc.get("esc50-1-20001-A-1")
    assert clip.licence == "NOASSERTION" and clip.source == "ESC-50"
    x = clip.load()
    assert x.dtype == np.float32 and len(x) == 16000 == round(clip.duration_s * 16000)
    spectrum = np.abs(np.fft.rfft(x * np.hanning(len(x))))
    assert np.argmax(spectrum) == pytest.approx(2000, abs=1)  # 1 Hz bins: the sine survives
    assert np.max(np.abs(x[200:-200])) == pytest.approx(0.5, abs=0.01)


def test_load_esc50_options(esc50_dir):
    esc = load_esc50(
        esc50_dir, heldout_folds=(1, 2), sample_rate=8000, max_duration_s=0.5, categories=["dog"]
    )
    assert esc.categories == ["dog"]
    assert len(esc.clips(split="heldout")) == 2
    clip = esc.clips()[0]
    assert clip.sample_rate == 8000 and clip.duration_s == 0.5
    assert len(clip.load()) == 4000
    with pytest.raises(ConfigError, match=r"categories \['unicorn'\] are not in .*available"):
        load_esc50(esc50_dir, categories=["unicorn"])
    with pytest.raises(ConfigError, match="heldout_folds must be among ESC-50's folds 1..5"):
        load_esc50(esc50_dir, heldout_folds=(6,))


def test_load_esc50_errors_name_what_is_missing(tmp_path, esc50_dir):
    with pytest.raises(AssetError, match="ESC-50 directory not found"):
        load_esc50(tmp_path / "nowhere")
    (tmp_path / "a.txt").write_text("x")  # it was called "not found"
    with pytest.raises(AssetError, match="ESC-50 directory is a file, not a directory"):
        load_esc50(tmp_path / "a.txt")
    (esc50_dir / "audio" / "3-10003-A-0.wav").unlink()
    with pytest.raises(AssetError, match=r"1 clip\(s\) listed .* missing .*: 3-10003-A-0\.wav"):
        load_esc50(esc50_dir)

    meta = esc50_dir / "meta" / "esc50.csv"
    rows = list(csv.reader(meta.open()))
    drop = rows[0].index("fold")
    with meta.open("w", newline="") as f:
        csv.writer(f).writerows([r[:drop] + r[drop + 1 :] for r in rows])
    with pytest.raises(AssetError, match=r"lacks column\(s\) \['fold'\]; an ESC-50 CSV has"):
        load_esc50(esc50_dir)

    meta.unlink()
    with pytest.raises(AssetError, match=r"meta/esc50\.csv"):
        load_esc50(esc50_dir)


def test_load_esc50_rejects_bad_rows(tmp_path):
    root = _make_esc50(tmp_path / "e", [("1-1-A-0.wav", 7, "dog", 300.0)])
    with pytest.raises(AssetError, match=r"esc50\.csv:2: fold must be 1\.\.5, got '7'"):
        load_esc50(root)
