"""Out-of-bank sounds found and refused through the open vocabulary (a small seeded run)."""

from __future__ import annotations

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.mapping.encoders.audio import MelCNNAudioEncoder
from tabletop.mapping.encoders.minilm import MiniLMTextEncoder
from tabletop.sim.sound_bank import SoundBank
from tabletop.train.audio_open import evaluate_open_sounds


def _first_clips(bank, n: int) -> SoundBank:
    """A small bank: the first held-out clip of ``bank``'s first ``n`` categories."""
    clips = [bank.clips(k, split="heldout")[0] for k in bank.categories[:n]]
    captions = {c.category: c.caption for c in clips}
    return SoundBank(clips, sample_rate=bank.sample_rate, captions=captions, name=f"first {n}")


def test_out_of_bank_figures_are_shares_and_seeded():
    full = SoundBank.out_of_bank()
    assert len(full.categories) >= 10  # the issue asks for 10 or more categories the bank lacks
    oob, bank = _first_clips(full, 6), _first_clips(SoundBank.default(), 3)
    kw = {"bank": bank, "n_maps": 4, "text_encoder": MiniLMTextEncoder()}
    a = evaluate_open_sounds(oob, **kw)
    assert set(a) == {"audio_open_found", "audio_open_refused", "n_open_categories", "n_open_clips"}
    assert 0 <= a["audio_open_found"] <= 1 and 0 <= a["audio_open_refused"] <= 1
    assert (a["n_open_categories"], a["n_open_clips"]) == (6, 6)
    # found only where the caption reaches the operating point: never at an impossible one
    never = evaluate_open_sounds(oob, threshold=1.01, **kw)
    assert never["audio_open_found"] == 0 and never["audio_open_refused"] == 1
    assert evaluate_open_sounds(oob, **kw) == a
    with pytest.raises(ConfigError, match="5 or more"):
        evaluate_open_sounds(_first_clips(full, 4), **kw)


def test_an_encoder_without_class_logits_is_refused_by_name():
    with pytest.raises(ConfigError, match="no open vocabulary"):
        evaluate_open_sounds(SoundBank.out_of_bank(), MelCNNAudioEncoder())


def test_the_scorer_is_fitted_on_training_clips_to_refuse_what_did_not_play():
    from tabletop.mapping.encoders.yamnet import yamnet_class_names
    from tabletop.mapping.open_sounds import OpenSoundVocabulary
    from tabletop.train.audio_open import fit_open_scorer

    base = SoundBank.default()
    clips = [base.clips(k, split="train")[0] for k in base.categories[::6]]
    bank = SoundBank(clips, sample_rate=base.sample_rate, name="every sixth")
    text = MiniLMTextEncoder()
    sc = fit_open_scorer(bank, text_encoder=text, n_maps=20, refused_aim=0.9)
    assert sc.null.shape == (521,) and np.isfinite([sc.w_rel, sc.w_abs, sc.bias]).all()
    assert sc.meta["train_refused"] >= 0.9 and 0 <= sc.meta["train_found"] <= 1
    assert sc.meta["fitted_on"].startswith(f"every sixth: {len(clips)} training clips")
    OpenSoundVocabulary(yamnet_class_names(), text, scorer=sc)  # of YAMNet's names
    few = SoundBank(clips[:3], sample_rate=base.sample_rate, name="three")
    with pytest.raises(ConfigError, match="8 or more"):
        fit_open_scorer(few, text_encoder=text, n_maps=2)
    with pytest.raises(ConfigError, match="no training clips"):
        fit_open_scorer(_first_clips(base, 3), text_encoder=text, n_maps=2)
