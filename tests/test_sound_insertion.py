"""Which categories a scan inserts: the shipped bank pins them, so growing it changes no scan."""

import numpy as np
import pytest

from tabletop.errors import AssetError
from tabletop.sim import sound_bank as sb
from tabletop.sim.sound_insertion import _choose_categories


def test_the_shipped_bank_pins_the_categories_scans_insert():
    bank = sb.SoundBank.default()
    pinned = bank.scan_categories
    assert pinned is not None and len(pinned) == 34 and pinned <= set(bank.categories)
    rich = {c for c in bank.categories if len(bank.clips(category=c)) >= 6}
    assert rich - pinned, "the bank has grown past the pin: the pin is what keeps scans fixed"
    for seed in range(20):
        cats, _ = _choose_categories(bank, np.random.default_rng([seed, 1]), 6, 1, "heldout", 6)
        assert set(cats) <= pinned


def test_a_bank_without_a_pin_inserts_any_category():
    bank = sb.SoundBank.default()
    free = sb.SoundBank(list(bank), sample_rate=bank.sample_rate, captions=bank.captions)
    assert free.scan_categories is None
    seen = set()
    for seed in range(60):
        cats, _ = _choose_categories(free, np.random.default_rng([seed, 1]), 6, 1, "heldout", 6)
        seen.update(cats)
    assert seen - bank.scan_categories  # the categories past the pin are drawn too


def test_a_pin_naming_a_category_the_bank_lacks_is_refused(tmp_path, monkeypatch):
    pin = tmp_path / "scan_categories.toml"
    pin.write_text('categories = ["dog", "unicorn"]\n')
    monkeypatch.setattr(sb, "SCAN_CATEGORIES_PATH", pin)
    sb._default_bank.cache_clear()
    try:
        with pytest.raises(AssetError, match=r"\['unicorn'\] are not in the bank"):
            sb._default_bank()
    finally:
        sb._default_bank.cache_clear()
