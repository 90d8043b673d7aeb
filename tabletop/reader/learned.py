"""The learned reader: MiniLM word features, a small tagger, and a structure decoder.

Each word of a request gets two labels from one network (``TaggerNet``: residual convolutions
over all-MiniLM-L6-v2's frozen, already contextual token states):

- its **role** (:data:`ROLES`): outside any reference (``O``), a step boundary (``THEN``), a
  repetition count (``REP``), or inside a reference: the first or a later word (``B-``/``I-``)
  of an object, a sound, a table place or an image, either the step's own goal (``OBJ`` ...)
  or a constraint on it (``NOBJ`` ...: "the mug *near the dog barking*");
- the **relation** of the step it belongs to (:data:`RELATIONS`): go to, between, a side of,
  above, back and forth, or a motion the grammar reads (compass moves, a base's own motions).

:func:`decode` turns the labels into the same plan the rule reader makes
(:mod:`tabletop.reader.plan`): references become typed parts, constraints narrow the goal
before them, the step's relation picks the action. A step labelled ``motion`` is handed to
the rule reader, which reads numbers and units exactly. The network is trained by ``tabletop
train reader`` (:mod:`tabletop.train.reader`) on generated requests; its weights are
``tabletop/data/weights/reader.pt``.
"""

from __future__ import annotations

import functools
import itertools
import logging
import re
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError
from tabletop.paths import DATA_DIR
from tabletop.reader.errors import ParseError
from tabletop.reader.plan import (
    Above,
    BackAndForth,
    Between,
    Goal,
    GoTo,
    Part,
    Side,
    Step,
)

__all__ = [
    "DEFAULT_READER_WEIGHTS",
    "RELATIONS",
    "ROLES",
    "LearnedTagger",
    "TaggerConfig",
    "best_roles",
    "decode",
    "load_tagger",
    "save_tagger",
]

log = logging.getLogger(__name__)

DEFAULT_READER_WEIGHTS = DATA_DIR / "weights" / "reader.pt"
READER_WEIGHTS_FORMAT = "tabletop-reader-tagger"
#: Reference kinds, as the plan's part kinds (obj, sound, area, img).
_KINDS = {"OBJ": "obj", "SOUND": "sound", "AREA": "area", "IMG": "img"}
ROLES: tuple[str, ...] = (
    "O",
    "THEN",
    "REP",
    *(f"{b}-{n}{k}" for n in ("", "N") for k in _KINDS for b in ("B", "I")),
)
RELATIONS: tuple[str, ...] = (
    "goto",
    "between",
    "left",
    "right",
    "front",
    "behind",
    "above",
    "backforth",
    "motion",
)
_SIDES = ("left", "right", "front", "behind")
#: Count words of a repetition.
_COUNTS = {"once": 1, "twice": 2, "thrice": 3, "one": 1, "two": 2, "three": 3, "four": 4}
_COUNTS |= {"five": 5, "six": 6, "seven": 7, "eight": 8, "nine": 9, "ten": 10}
_WORD_RE = re.compile(r"\S+")


@dataclass(frozen=True)
class TaggerConfig:
    """The tagger's shape (stored with its weights)."""

    hidden: int = 160
    """Channels of the convolution over the words."""
    kernel: int = 3
    """Words each convolution sees (odd)."""
    layers: int = 2
    """Stacked convolutions (each with a residual connection)."""
    dropout: float = 0.2
    """Dropout on the MiniLM states and between layers (training only)."""
    feature_dim: int = 384
    """MiniLM's token state size."""

    def __post_init__(self) -> None:
        if self.hidden < 1 or self.layers < 1 or self.feature_dim < 1:
            raise ConfigError(f"hidden, layers and feature_dim must be >= 1, got {self}")
        if self.kernel < 1 or self.kernel % 2 == 0:
            raise ConfigError(f"kernel must be an odd number >= 1, got {self.kernel}")
        if not 0 <= self.dropout < 1:
            raise ConfigError(f"dropout must be in [0, 1), got {self.dropout}")


def _net(cfg: TaggerConfig):
    import torch
    from torch import nn

    class TaggerNet(nn.Module):
        """(B, T, feature_dim) word features -> role and relation logits (B, T, ·).

        MiniLM's states already carry each word's context; a projection and residual
        convolutions over neighbouring words (padding masked out) add what the labels need
        from a few words around, at a fraction of a recurrent network's cost on a CPU."""

        def __init__(self) -> None:
            super().__init__()
            self.drop = nn.Dropout(cfg.dropout)
            self.inp = nn.Linear(cfg.feature_dim, cfg.hidden)
            self.convs = nn.ModuleList(
                nn.Conv1d(cfg.hidden, cfg.hidden, cfg.kernel, padding=cfg.kernel // 2)
                for _ in range(cfg.layers)
            )
            self.norms = nn.ModuleList(nn.LayerNorm(cfg.hidden) for _ in range(cfg.layers))
            self.role = nn.Linear(cfg.hidden, len(ROLES))
            self.relation = nn.Linear(cfg.hidden, len(RELATIONS))

        def forward(self, x: torch.Tensor, lengths: torch.Tensor):
            mask = (torch.arange(x.shape[1])[None, :] < lengths[:, None]).to(x.device)
            mask = mask[..., None].float()
            h = nn.functional.gelu(self.inp(self.drop(x))) * mask
            for conv, norm in zip(self.convs, self.norms, strict=True):
                c = conv(self.drop(h).transpose(1, 2)).transpose(1, 2)
                h = norm(h + nn.functional.gelu(c)) * mask
            return self.role(h), self.relation(h)

    return TaggerNet()


@functools.cache
def _minilm():
    """MiniLM's tokenizer and transformer (the same weights as the text encoder)."""
    from tabletop.mapping.encoders.minilm import _load_model

    st = _load_model()
    return st.tokenizer, st[0].auto_model.eval()


def words_of(text: str) -> list[str]:
    """The words a request is tagged by: whitespace-separated, punctuation kept on the word."""
    return _WORD_RE.findall(text)


def word_features(sentences: list[list[str]], batch: int = 64) -> list[np.ndarray]:
    """MiniLM's last-layer state of each word's first word piece: one (n_words, 384) float32
    array per sentence (frozen; no gradient)."""
    import torch

    tok, model = _minilm()
    device = next(model.parameters()).device
    out: list[np.ndarray] = []
    for i in range(0, len(sentences), batch):
        chunk = sentences[i : i + batch]
        enc = tok(chunk, is_split_into_words=True, return_tensors="pt", padding=True,
                  truncation=True, max_length=128)  # fmt: skip
        with torch.inference_mode():
            ids, mask = enc["input_ids"].to(device), enc["attention_mask"].to(device)
            h = model(input_ids=ids, attention_mask=mask)[0].float().cpu()
        h = h.numpy()
        for j, words in enumerate(chunk):
            first: dict[int, int] = {}
            for t, w in enumerate(enc.word_ids(j)):
                if w is not None and w not in first:
                    first[w] = t
            rows = [first.get(w, max(first.values(), default=0)) for w in range(len(words))]
            out.append(np.ascontiguousarray(h[j, rows], dtype=np.float32))
    return out


class LearnedTagger:
    """The trained tagger: ``tag(words)`` -> (roles, relations), one label each per word."""

    def __init__(self, config: TaggerConfig, state: dict, meta: dict | None = None) -> None:
        import torch

        self.config = config
        self.meta = dict(meta or {})
        self.net = _net(config)
        self.net.load_state_dict({k: v.float() for k, v in state.items()})
        self.net.eval()
        self._torch = torch

    def tag(self, words: list[str]) -> tuple[list[str], np.ndarray]:
        """Each word's role, and each word's log-probabilities of its step's relation
        ((n_words, len(RELATIONS)) float32)."""
        if not words:
            return [], np.zeros((0, len(RELATIONS)), np.float32)
        torch = self._torch
        (feats,) = word_features([words])
        with torch.inference_mode():
            x = torch.from_numpy(feats)[None]
            role, rel = self.net(x, torch.tensor([len(words)]))
        roles = best_roles(torch.log_softmax(role[0], dim=-1).numpy())
        return roles, torch.log_softmax(rel[0], dim=-1).numpy()


@functools.cache
def _allowed() -> np.ndarray:
    """(R, R) bool: may role j follow role i (a reference continues only what it began)."""
    ok = np.ones((len(ROLES), len(ROLES)), bool)
    for j, r in enumerate(ROLES):
        if r.startswith("I-"):
            ok[:, j] = [p[2:] == r[2:] for p in ROLES]
    return ok


def best_roles(logp: np.ndarray) -> list[str]:
    """The most likely roles of a request's words, (T, R) log-probabilities in, under the rule
    that a reference's later words (``I-``) follow its first (Viterbi)."""
    if len(logp) == 0:
        return []
    ok = _allowed()
    first_ok = np.array([not r.startswith("I-") for r in ROLES])
    score = np.where(first_ok, logp[0], -np.inf)
    back = []
    for t in range(1, len(logp)):
        cand = np.where(ok, score[:, None], -np.inf)  # (prev, cur)
        back.append(cand.argmax(axis=0))
        score = cand.max(axis=0) + logp[t]
    path = [int(score.argmax())]
    for b in reversed(back):
        path.append(int(b[path[-1]]))
    return [ROLES[i] for i in reversed(path)]


def save_tagger(path: str | Path, config: TaggerConfig, net, meta: dict) -> Path:
    """Write the tagger's weights (fp16), config and ``meta`` (figures) to ``path``."""
    import torch

    from tabletop.atomic import atomic_path

    state = {k: v.detach().half() for k, v in net.state_dict().items()}
    doc = {"format": READER_WEIGHTS_FORMAT, "version": 1, "config": asdict(config),
           "meta": meta, "state": state}  # fmt: skip
    path = Path(path)
    with atomic_path(path) as tmp:
        torch.save(doc, tmp)
    return path


@functools.cache
def load_tagger(path: str | Path = DEFAULT_READER_WEIGHTS) -> LearnedTagger:
    """The tagger stored at ``path`` (:class:`AssetError` naming the problem otherwise)."""
    import torch

    p = Path(path)
    if not p.is_file():
        raise AssetError(
            f"reader weights {str(p)!r} do not exist; train them with `tabletop train reader`"
        )
    try:
        doc = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as e:  # torch raises many types for a damaged file
        raise AssetError(f"reader weights {str(p)!r} are unreadable: {e}") from None
    if not isinstance(doc, dict) or doc.get("format") != READER_WEIGHTS_FORMAT:
        raise AssetError(f"{str(p)!r} is not a reader tagger (format {READER_WEIGHTS_FORMAT!r})")
    return LearnedTagger(TaggerConfig(**doc["config"]), doc["state"], doc.get("meta"))


# ---------------------------------------------------------------------------- decoding
@dataclass(frozen=True)
class _Span:
    kind: str  # obj, sound, area, img
    near: bool
    text: str


def _spans(words: list[str], roles: list[str]) -> list[_Span]:
    """References as tagged: a run of words with one reference label (``B-`` starts a new
    one only after a word outside it: no request puts two references side by side)."""
    spans: list[_Span] = []
    cur: list[str] = []
    tag = ""
    for w, r in [*zip(words, roles, strict=True), ("", "O")]:
        body = r[2:] if r[:2] in ("B-", "I-") else ""
        if cur and body != tag:
            near = tag.startswith("N")
            text = " ".join(cur).strip(" ,.;:!?\"'")
            if text:
                spans.append(_Span(_KINDS[tag[1:] if near else tag], near, text))
            cur, tag = [], ""
        if body:
            cur.append(w)
            tag = body
    return spans


def _goals(spans: list[_Span]) -> list[Goal]:
    goals: list[Goal] = []
    for s in spans:
        part = Part(s.kind, _bare(s.text))
        if s.near and goals:
            goals[-1] = Goal(goals[-1].primary, (*goals[-1].near, part))
        else:
            goals.append(Goal(part))
    return goals


def _bare(text: str) -> str:
    """A reference's words without a leading article (how the rule reader passes them)."""
    text = re.sub(r"\s+", " ", text.lower()).strip(" ,.;:!?\"'")
    return re.sub(r"^(?:(?:the|a|an|some|any|that|this)\s+)+", "", text)


def _landmark(goal: Goal) -> str | Goal:
    return goal.primary.text if not goal.near and goal.primary.kind == "obj" else goal


#: A count said as "N times" beyond this is refused by the step check, wherever it was tagged.
MAX_TIMES_SAID = 20


def _said_times(words: list[str]) -> int | None:
    """N of an "N times" (digits or a count word) in ``words``, else None."""
    low = [w.lower().strip(" ,.;:!?") for w in words]
    for a, b in itertools.pairwise(low):
        if b == "times" and (a.isdigit() or a in _COUNTS):
            return int(a) if a.isdigit() else _COUNTS[a]
    return None


def _count(words: list[str]) -> int:
    n = 1
    for w in words:
        w = w.lower().strip(" ,.;:!?")
        if w.isdigit():
            n = int(w)
        elif w in _COUNTS:
            n = _COUNTS[w]
    return n


def _relation(scores: np.ndarray) -> str:
    """The step's relation: the most likely over its words (summed log-probabilities)."""
    return RELATIONS[int(np.argmax(scores.sum(axis=0)))]


def _check(text: str, clause: str, relation: str, goals: list[Goal], times: int) -> None:
    """Refuse what the plan cannot honour, as the grammar does: a relation without the
    places it takes (or with more), a place named only by a pointing word, a side or above of
    something that is not a thing, too many repetitions."""
    from tabletop.reader.rules import MAX_REPEAT, POINTERS

    need = 2 if relation in ("between", "backforth") else 1
    if len(goals) != need:
        raise ParseError(
            text, clause, f"'{relation}' takes {need} place(s); the step names {len(goals)}"
        )
    for g in goals:
        for part in (g.primary, *g.near):
            if part.kind != "img" and set(part.text.split()) <= POINTERS:
                raise ParseError(text, part.text, "a word that points back names no place")
    if relation in (*_SIDES, "above") and goals[0].primary.kind != "obj":
        raise ParseError(
            text, clause, f"'{relation}' is taken of a thing, not a {goals[0].primary.kind}"
        )
    if not 1 <= times <= MAX_REPEAT:
        raise ParseError(text, clause, f"repeat 1 to {MAX_REPEAT} times, not {times}")


def decode(text: str, words: list[str], roles: list[str], relations, robot: str,
           rules) -> tuple[Step, ...]:  # fmt: skip
    """The plan of tagged ``words``; ``relations`` are each word's relation label or its
    (n_words, len(RELATIONS)) log-probabilities; ``rules(clause, robot)`` reads a ``motion``
    step.

    Raises:
        ParseError: a step has no reference.
    """
    if not isinstance(relations, np.ndarray):  # labels: a one-hot score per word
        index = {r: i for i, r in enumerate(RELATIONS)}
        onehot = np.full((len(words), len(RELATIONS)), -1e3, np.float32)
        onehot[np.arange(len(words)), [index[r] for r in relations]] = 0.0
        relations = onehot
    steps: list[Step] = []
    if roles and roles[-1] == "THEN":
        raise ParseError(text, text, "an empty step: a joining word must join two steps")
    chunks: list[list[int]] = [[]]
    for i, r in enumerate(roles):
        if r == "THEN":
            if chunks[-1]:
                chunks.append([])
        else:
            chunks[-1].append(i)
    for idx in (c for c in chunks if c):
        clause = " ".join(words[i] for i in idx)
        times = _count([words[i] for i in idx if roles[i] == "REP"])
        said = _said_times([words[i] for i in idx])
        if said is not None and (times == 1 or said > MAX_TIMES_SAID):
            times = said  # "N times" read inside a reference still counts
        goals = _goals(_spans([words[i] for i in idx], [roles[i] for i in idx]))
        relation = _relation(relations[idx])
        if relation == "motion":
            steps.extend(rules(clause, robot))
            continue
        if not goals:
            raise ParseError(text, clause, "the step names nothing to go to")
        _check(text, clause, relation, goals, times)
        if relation == "between":
            action = Between(goals[0], goals[1])
        elif relation == "backforth":
            action = BackAndForth(goals[0], goals[1])
        elif relation in _SIDES:
            action = Side(relation, _landmark(goals[0]))
        elif relation == "above":
            action = Above(_landmark(goals[0]))
        else:
            action = GoTo(goals[0])
        steps.append(Step(action, times, clause))
    if not steps:
        raise ParseError(text, text, "the request names nothing to go to")
    return tuple(steps)
