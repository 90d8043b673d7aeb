"""Query-side alternatives to the audio vocabulary's text prototypes, measured without retraining.

On the validation split of ``tools/audio_validation.py`` (the training clips less the last of
every category with three or more; the bank's held-out clips are never loaded), with a network
trained without the validation clips (``--weights``, e.g. the checkpoint that tool writes):

- ``text``: the shipped posterior, the scaled cosine with each category's text prototype;
- ``audio``: prototypes from the network's own embeddings of the remaining training clips
  (``--crops`` seeded crops of 0.5-3 s per clip in noise at 5-25 dB), and mixes of the two;
- ``knn``: a soft nearest-neighbour vote over those training embeddings;
- ``windows``: each validation segment embedded whole against the mean of the embeddings, or of
  the posteriors, of 1 s and 1.5 s windows at half-window hops (and the whole segment).

Prints audio-to-text and text-to-audio recall@1/@3 (as ``evaluate_audio`` defines them) at
15 dB and, for the windows, at 5 dB.

    python tools/audio_query_side.py --weights out/audval/cheap.pt
"""

from __future__ import annotations

import argparse

import numpy as np

from tabletop.mapping.encoders.audio import MelCNNAudioEncoder
from tabletop.mapping.encoders.minilm import MiniLMTextEncoder
from tabletop.mapping.sound_vocabulary import SoundMatcher
from tabletop.sim.sound_bank import SoundBank
from tabletop.train.audio import _eval_segment, _recall_at, make_segment

try:  # run as a script from the repository root
    from audio_validation import validation_bank
except ImportError:  # pragma: no cover
    from tools.audio_validation import validation_bank


def _lse(z: np.ndarray) -> np.ndarray:
    mx = z.max(axis=1, keepdims=True)
    return (mx + np.log(np.exp(z - mx).sum(axis=1, keepdims=True)))[:, 0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--weights", required=True, help="a checkpoint trained without the val clips")
    ap.add_argument("--crops", type=int, default=6, help="training crops per clip")
    args = ap.parse_args()
    bank = validation_bank(SoundBank.default())
    enc = MelCNNAudioEncoder(args.weights)
    rate, vocab = bank.sample_rate, enc.vocabulary
    matcher = SoundMatcher(vocab, MiniLMTextEncoder(), words={})
    cats = vocab.categories
    _, _, text_proto = matcher.targets()

    emb, lab = [], []
    for i, clip in enumerate(bank.clips(split="train")):
        x = np.asarray(clip.load(), np.float32)
        for k in range(args.crops):
            rng = np.random.default_rng([1234, i, k])
            n = min(len(x), int(rng.uniform(0.5, 3.0) * rate))
            s0 = int(rng.integers(0, max(1, len(x) - n + 1)))
            crop = x[s0 : s0 + n]
            snr = float(rng.uniform(5, 25))
            seg = make_segment(
                crop, rate, (n + round(0.2 * rate)) / rate, rng, snr_db=snr, margin_s=0.1
            )
            emb.append(enc.encode_audio(seg, rate))
            lab.append(cats.index(clip.category))
    emb, lab = np.stack(emb), np.array(lab)
    audio_proto = np.stack(
        [emb[lab == j].mean(0) if (lab == j).any() else text_proto[j] for j in range(len(cats))]
    )
    audio_proto /= np.linalg.norm(audio_proto, axis=1, keepdims=True)

    held = bank.clips(split="heldout")
    cat = np.array([cats.index(c.category) for c in held])
    rel = cat[:, None] == np.arange(len(cats))[None]
    asked = sorted(set(cat.tolist()))

    def report(name: str, z: np.ndarray) -> None:
        lo = np.stack([z[:, j] - _lse(np.delete(z, j, 1)) for j in asked])
        print(
            f"{name:32s} audio->text @1 {_recall_at(z, rel, 1):.3f} @3 {_recall_at(z, rel, 3):.3f}"
            f"  text->audio @1 {_recall_at(lo, rel[:, asked].T, 1):.3f}"
            f" @3 {_recall_at(lo, rel[:, asked].T, 3):.3f}",
            flush=True,
        )

    scale = vocab.logit_scale
    for snr in (15.0, 5.0):
        segs = [
            _eval_segment(c.load(), rate, np.random.default_rng([0, i]), snr)
            for i, c in enumerate(held)
        ]
        whole = np.stack([enc.encode_audio(s, rate) for s in segs])
        report(f"text prototypes, {snr:.0f} dB", scale * whole @ text_proto.T)
        if snr == 15.0:
            report("audio prototypes", scale * whole @ audio_proto.T)
            for w in (0.3, 0.5, 0.7):
                p = w * audio_proto + (1 - w) * text_proto
                report(
                    f"mix, audio weight {w}",
                    scale * whole @ (p / np.linalg.norm(p, axis=1, keepdims=True)).T,
                )
            zz = scale * whole @ emb.T
            knn = np.stack(
                [_lse(zz[:, lab == j]) if (lab == j).any() else np.full(len(whole), -1e9)
                 for j in range(len(cats))], 1)  # fmt: skip
            report("soft nearest neighbours", knn)
        for win in (1.0, 1.5):
            mean_emb, mean_post = [], []
            for s in segs:
                n = int(win * rate)
                starts = list(range(0, max(1, len(s) - n + 1), n // 2)) or [0]
                e = np.stack(
                    [enc.encode_audio(s[a : a + n], rate) for a in starts]
                    + [enc.encode_audio(s, rate)]
                )
                m = e.mean(0)
                mean_emb.append(m / np.linalg.norm(m))
                z = scale * e @ text_proto.T
                mean_post.append(np.log(np.exp(z - _lse(z)[:, None]).mean(0) + 1e-12))
            report(f"{win} s windows, mean embedding", scale * np.stack(mean_emb) @ text_proto.T)
            report(f"{win} s windows, mean posterior", np.stack(mean_post))


if __name__ == "__main__":
    main()
