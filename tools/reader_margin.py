"""Plans right on the validation pools' generated requests at each joint-reading margin
(:data:`tabletop.reader.learned.JOINT_MARGIN`), for the network trained without them:

    python tools/reader_margin.py out/weights/reader.pt

Generated texts only (the tune pools' words in the project's templates); never an evaluation
suite.
"""

import sys

import numpy as np
import torch

from tabletop.cli.language import READER_TEXTS_PER_POOL, READER_VAL_POOLS
from tabletop.eval.paraphrase import TUNE_POOLS
from tabletop.eval.reader_texts import reader_texts
from tabletop.reader.errors import ParseError
from tabletop.reader.learned import best_roles, decode, load_tagger
from tabletop.train.reader import _features, _rules, plan_key

tagger = load_tagger(sys.argv[1])
if tagger.meta.get("trained_without") != list(READER_VAL_POOLS):
    raise SystemExit(f"{sys.argv[1]} was not trained without {READER_VAL_POOLS}")
texts = reader_texts(TUNE_POOLS, n_per_pool=READER_TEXTS_PER_POOL, seed=0)
feats = _features(texts, __import__("pathlib").Path("out/cache"))
val = [(f, t) for f, t in zip(feats, texts, strict=True) if t.pool in READER_VAL_POOLS]
scored = []
with torch.inference_mode():
    for f, t in val:
        role, rel = tagger.net(torch.from_numpy(f)[None], torch.tensor([len(f)]))
        scored.append(
            (t, torch.log_softmax(role[0], -1).numpy(), torch.log_softmax(rel[0], -1).numpy())
        )


def key(text, words, roles, rels, role_logp=None, margin=0.0):
    try:
        return plan_key(decode(text, words, roles, rels, "arm", _rules, role_logp, margin))
    except ParseError:
        return "refused"


for margin in (0.0, 2.0, 4.0, 6.0, 8.0, 12.0, 20.0, np.inf):
    right = refused_right = refusals = 0
    for t, role_logp, rel_logp in scored:
        words = list(t.words)
        gold = key(t.text, words, list(t.roles), list(t.relations))
        got = key(t.text, words, best_roles(role_logp), rel_logp, role_logp, margin)
        right += got == gold
        refusals += gold == "refused"
        refused_right += gold == got == "refused"
    print(
        f"margin {margin:5}: plans right {right / len(scored):.3f} "
        f"(refusals refused {refused_right}/{refusals})"
    )
