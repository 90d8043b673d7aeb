"""Training the learned reader's tagger (:mod:`tabletop.reader.learned`; ``tabletop train
reader``).

The texts (:func:`tabletop.eval.reader_texts.reader_texts`, which the CLI passes in) are
requests generated from the tune pools' words and the project's own templates, each word
labelled with its role and its step's relation. MiniLM stays frozen: its word states are
computed once and cached (``cache_dir``), so a run costs a few minutes on two cores and a
stopped run resumes from the cache. Seeded; the figures go into the weights' ``meta``:

- on texts of ``val_pools`` (pools the network that is measured never saw), how many words
  get the right role and relation, and how many requests decode to the right plan;
- the same requests read by the rule reader (with its spelling pass), for comparison.

The committed network is then fitted on every pool's texts.
"""

from __future__ import annotations

import hashlib
import logging
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from tabletop.reader.learned import (
    RELATIONS,
    ROLES,
    LearnedTagger,
    TaggerConfig,
    _net,
    best_roles,
    decode,
    save_tagger,
    word_features,
)

__all__ = ["plan_key", "train_reader"]

log = logging.getLogger(__name__)


def _features(texts, cache_dir: Path | None) -> list[np.ndarray]:
    sentences = [list(t.words) for t in texts]
    key = hashlib.sha256("\n".join(" ".join(s) for s in sentences).encode()).hexdigest()[:16]
    path = cache_dir / f"reader_features_{key}.npz" if cache_dir else None
    if path is not None and path.is_file():
        with np.load(path) as z:
            flat, lengths = z["flat"], z["lengths"]
        return np.split(flat.astype(np.float32), np.cumsum(lengths)[:-1])
    feats = word_features(sentences)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, flat=np.concatenate(feats).astype(np.float16),
                 lengths=np.array([len(f) for f in feats]))  # fmt: skip
    return feats


def _fit(feats, texts, cfg: TaggerConfig, epochs: int, seed: int, progress=None, device="cpu"):
    import torch
    from torch import nn

    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    net = _net(cfg).to(device)
    opt = torch.optim.AdamW(net.parameters(), lr=3e-3, weight_decay=1e-4)
    role_ix = {r: i for i, r in enumerate(ROLES)}
    rel_ix = {r: i for i, r in enumerate(RELATIONS)}
    ys = [(np.array([role_ix[r] for r in t.roles]), np.array([rel_ix[r] for r in t.relations]))
          for t in texts]  # fmt: skip
    loss_fn = nn.CrossEntropyLoss(ignore_index=-1)
    batch = 128
    steps = epochs * ((len(texts) + batch - 1) // batch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=3e-3, total_steps=steps)
    net.train()
    for epoch in range(epochs):
        order = rng.permutation(len(texts))
        total = 0.0
        for i in range(0, len(order), batch):
            idx = order[i : i + batch]
            lengths = torch.tensor([len(feats[j]) for j in idx])
            tmax = int(lengths.max())
            x = torch.zeros(len(idx), tmax, cfg.feature_dim)
            y_role = torch.full((len(idx), tmax), -1, dtype=torch.long)
            y_rel = torch.full((len(idx), tmax), -1, dtype=torch.long)
            for k, j in enumerate(idx):
                n = len(feats[j])
                x[k, :n] = torch.from_numpy(feats[j])
                y_role[k, :n] = torch.from_numpy(ys[j][0])
                y_rel[k, :n] = torch.from_numpy(ys[j][1])
            x, y_role, y_rel = x.to(device), y_role.to(device), y_rel.to(device)
            role, rel = net(x, lengths)
            loss = loss_fn(role.reshape(-1, len(ROLES)), y_role.reshape(-1)) + loss_fn(
                rel.reshape(-1, len(RELATIONS)), y_rel.reshape(-1)
            )
            opt.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(net.parameters(), 5.0)
            opt.step()
            sched.step()
            total += float(loss.detach()) * len(idx)
        log.info("reader epoch %d/%d: loss %.4f", epoch + 1, epochs, total / len(texts))
        if progress is not None:
            progress(epoch + 1, epochs)
    net.eval()
    return net.cpu()


def plan_key(steps) -> tuple:
    """What a plan asks, comparable across readers: per step the action, its repetitions and
    each goal's parts as (kind, words) — an area's words are left out, since the rule reader
    names areas by the map's own names."""
    from tabletop.reader.plan import Goal

    def part(p):
        return (p.kind, None if p.kind == "area" else " ".join(p.text.lower().split()))

    def goal(g):
        if isinstance(g, str):
            return (("obj", " ".join(g.lower().split())),)
        return (part(g.primary), *(part(p) for p in g.near)) if isinstance(g, Goal) else (g,)

    out = []
    for s in steps:
        a = s.action
        fields = []
        for name in ("goal", "a", "b", "landmark"):
            if hasattr(a, name):
                fields.append(goal(getattr(a, name)))
        for name in ("side", "direction", "distance_m"):
            if hasattr(a, name):
                fields.append(getattr(a, name))
        out.append((type(a).__name__, s.times, *fields))
    return tuple(out)


def _rules(clause: str, robot: str):
    from tabletop.reader.reading import read_clause

    return read_clause(clause, robot)


def _plans_right(texts, tagged: Callable[[int], tuple], reader=None) -> float:
    from tabletop.reader.errors import ParseError

    right = 0
    for i, t in enumerate(texts):
        words = list(t.words)
        refuse = "none" in t.relations
        try:
            gold = plan_key(decode(t.text, words, list(t.roles), list(t.relations), "arm", _rules))
        except ParseError:
            if not refuse:
                continue  # a generated text whose own labels make no plan: counted as a miss
            gold = "refused"
        try:
            if reader is not None:
                got = plan_key(reader(t.text))
            else:
                roles, rels, role_logp = tagged(i)
                got = plan_key(decode(t.text, words, roles, rels, "arm", _rules, role_logp))
        except ParseError:
            got = "refused"
        right += got == gold
    return right / max(len(texts), 1)


def _measure(net, feats, texts) -> dict:
    import torch

    roles_ok = rels_ok = n = 0
    preds = []
    with torch.inference_mode():
        for f, t in zip(feats, texts, strict=True):
            role, rel = net(torch.from_numpy(f)[None], torch.tensor([len(f)]))
            pr = [ROLES[i] for i in role[0].argmax(-1).tolist()]
            pl = [RELATIONS[i] for i in rel[0].argmax(-1).tolist()]
            role_logp = torch.log_softmax(role[0], dim=-1).numpy()
            rel_logp = torch.log_softmax(rel[0], dim=-1).numpy()
            preds.append((best_roles(role_logp), rel_logp, role_logp))
            roles_ok += sum(a == b for a, b in zip(pr, t.roles, strict=True))
            rels_ok += sum(a == b for a, b in zip(pl, t.relations, strict=True))
            n += len(pr)
    return {
        "words_role_right": roles_ok / n,
        "words_relation_right": rels_ok / n,
        "plans_right": _plans_right(texts, lambda i: preds[i]),
    }


def train_reader(
    texts: Sequence,
    out: str | Path,
    val_pools: Sequence[str] = (),
    epochs: int = 12,
    seed: int = 0,
    cache_dir: str | Path | None = "out/cache",
    progress=None,
    device: str = "cpu",
    refit: bool = False,
) -> LearnedTagger:
    """Fit the tagger on ``texts`` (:class:`~tabletop.eval.reader_texts.ReaderText`) without
    those of ``val_pools``, measure it on theirs, and write it to ``out`` with the figures: so
    the figures describe the network written. ``refit``: then fit a second network on every
    text and write that one instead (the first goes beside ``out`` as ``<stem>_val.pt``).
    A network fitted without ``val_pools`` already at ``<stem>_val.pt`` for the same texts and
    seed is reused (a run stopped after it resumes there). ``device``: where the tagger trains
    (the MiniLM states come from wherever MiniLM was loaded)."""
    import torch

    from tabletop.reader.reading import get_reader

    t0 = time.perf_counter()
    cache = Path(cache_dir) if cache_dir is not None else None
    feats = _features(texts, cache)
    cfg = TaggerConfig()
    key = _texts_key(texts)
    meta: dict = {"seed": seed, "epochs": epochs, "texts": len(texts), "texts_key": key,
                  "pools": sorted({t.pool for t in texts})}  # fmt: skip
    if val_pools:
        tr = [i for i, t in enumerate(texts) if t.pool not in val_pools]
        va = [i for i, t in enumerate(texts) if t.pool in val_pools]
        val_out = Path(out).with_name(Path(out).stem + "_val.pt")
        val_meta = {"seed": seed, "epochs": epochs, "texts_key": key,
                    "trained_without": list(val_pools)}  # fmt: skip
        net = _resume(val_out, cfg, val_meta)
        if net is None:
            net = _fit(
                [feats[i] for i in tr], [texts[i] for i in tr], cfg, epochs, seed, progress, device
            )
            save_tagger(val_out, cfg, net, val_meta)
        val_texts = [texts[i] for i in va]
        figures = _measure(net, [feats[i] for i in va], val_texts)
        rules = get_reader("rules+spelling")
        figures["rules_plans_right"] = _plans_right(
            val_texts, None, lambda s: rules.understand(s).steps
        )
        meta["validation"] = {"pools": list(val_pools), "texts": len(va), **figures}
        meta["trained_without"] = list(val_pools)
        log.info("reader on pools it never saw: %s", meta["validation"])
    if refit or not val_pools:
        net = _fit(feats, list(texts), cfg, epochs, seed, progress, device)
        meta.pop("trained_without", None)
    meta["seconds"] = round(time.perf_counter() - t0, 1)
    meta["torch_threads"] = torch.get_num_threads()
    save_tagger(out, cfg, net, meta)
    return LearnedTagger(cfg, {k: v.detach() for k, v in net.state_dict().items()}, meta)


def _texts_key(texts) -> str:
    """A short hash of the texts and their labels (what a resumed network must have seen)."""
    h = hashlib.sha256()
    for t in texts:
        h.update(" ".join(t.words).encode())
        h.update(" ".join(t.roles).encode())
        h.update(" ".join(t.relations).encode())
        h.update(t.pool.encode())
    return h.hexdigest()[:16]


def _resume(path: Path, cfg: TaggerConfig, meta: dict):
    """The network at ``path`` if it was fitted with ``cfg`` and ``meta`` (else None)."""
    if not path.is_file():
        return None
    import torch

    from tabletop.reader.learned import load_tagger

    try:
        tagger = load_tagger.__wrapped__(path)
    except Exception:  # a damaged or foreign file: fit afresh
        return None
    if tagger.config != cfg or any(tagger.meta.get(k) != v for k, v in meta.items()):
        return None
    log.info("reader: resuming from %s", path)
    net = tagger.net
    for p in net.parameters():
        p.requires_grad_(False)
    return net.to(torch.float32)
