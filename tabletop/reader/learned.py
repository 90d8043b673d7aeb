"""The learned reader: MiniLM word features, a small tagger, and a structure decoder.

Each word of a request gets two labels from one network (``TaggerNet``: residual convolutions
over all-MiniLM-L6-v2's frozen, already contextual token states):

- its **role** (:data:`ROLES`): outside any reference (``O``), a step boundary (``THEN``), a
  repetition count (``REP``), or inside a reference: the first or a later word (``B-``/``I-``)
  of an object, a sound, a table place or an image, either the step's own goal (``OBJ`` ...)
  or a constraint on it (``NOBJ`` ...: "the mug *near the dog barking*");
- the **relation** of the step it belongs to (:data:`RELATIONS`): go to, between, a side of,
  above, back and forth, a motion the grammar reads (compass moves, a base's own motions), or
  ``none``: a request the arm must refuse (an action on a thing, a negated or conditional goal,
  chat with no place in it).

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
    MOTIONS,
    Above,
    BackAndForth,
    Between,
    Goal,
    GoTo,
    Part,
    Side,
    Step,
)
from tabletop.relations import SIDES

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
    "none",
)
_SIDES = SIDES
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

    def scores(self, words: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """Each word's role and relation log-probabilities ((n_words, len(ROLES)) and
        (n_words, len(RELATIONS)) float32), for :func:`decode`'s joint reading."""
        torch = self._torch
        if not words:
            return np.zeros((0, len(ROLES)), np.float32), np.zeros((0, len(RELATIONS)), np.float32)
        (feats,) = word_features([words])
        with torch.inference_mode():
            role, rel = self.net(torch.from_numpy(feats)[None], torch.tensor([len(words)]))
        return (torch.log_softmax(role[0], dim=-1).numpy(),
                torch.log_softmax(rel[0], dim=-1).numpy())  # fmt: skip


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
    best = k_best_roles(logp, 1)
    return best[0][1] if best else []


def k_best_roles(logp: np.ndarray, k: int) -> list[tuple[float, list[str]]]:
    """The ``k`` most likely role sequences of a request's words under the same rule as
    :func:`best_roles`, most likely first, each with its log-probability (list Viterbi: the
    ``k`` best paths into each role at each word). The first equals :func:`best_roles`'s."""
    if len(logp) == 0 or k < 1:
        return []
    n_roles = len(ROLES)
    ok = np.where(_allowed(), 0.0, -np.inf)  # (prev, cur)
    first_ok = np.array([not r.startswith("I-") for r in ROLES])
    # score[r, j]: the j-th best path ending in role r; only the first is set at the start
    score = np.full((n_roles, k), -np.inf)
    score[:, 0] = np.where(first_ok, logp[0], -np.inf)
    backs = []
    for t in range(1, len(logp)):
        cand = score[:, :, None] + ok[:, None, :] + logp[t][None, None, :]  # (prev, j, cur)
        flat = cand.reshape(n_roles * k, n_roles)
        order = np.argsort(-flat, axis=0, kind="stable")[:k]  # (k, cur): (prev, j) indices
        score = np.take_along_axis(flat, order, axis=0).T  # (cur, k)
        backs.append(order.T)  # (cur, k)
    flat_end = score.reshape(-1)
    out = []
    for idx in np.argsort(-flat_end, kind="stable")[:k]:
        if not np.isfinite(flat_end[idx]):
            break
        role, rank = divmod(int(idx), k)
        path = [role]
        for back in reversed(backs):
            role, rank = divmod(int(back[role, rank]), k)
            path.append(role)
        out.append((float(flat_end[idx]), [ROLES[i] for i in reversed(path)]))
    return out


@functools.cache
def _starts() -> tuple[np.ndarray, np.ndarray]:
    """(R, R) bool: role j after role i begins a new reference (as :func:`_spans` cuts them),
    and (R,) bool: role j is a goal's own reference (not a constraint on one)."""
    body = [r[2:] if r[:2] in ("B-", "I-") else "" for r in ROLES]
    start = np.array([[bj != "" and bj != bi for bj in body] for bi in body])
    own = np.array([b != "" and not b.startswith("N") for b in body])
    return start, own


#: Goals counted apart by the joint reading (a step takes at most 2; more is "too many").
_MAX_GOALS = 3


def goal_counts(
    logp: np.ndarray, banned: tuple[str, ...] = ("THEN",)
) -> list[tuple[float, list[str]]]:
    """For each number of goals n in 0 .. _MAX_GOALS (the last: that many or more), the most
    likely roles of a step's words that name exactly n goals, and their log-probability
    (-inf where none can). A goal begins where a reference begins that is a goal's own, or a
    constraint before any goal (:func:`_goals` makes that one a goal). Roles in ``banned``
    are not used (a step's words hold no step boundary)."""
    T, R = logp.shape
    C = _MAX_GOALS + 1
    out: list[tuple[float, list[str]]] = [(-np.inf, []) for _ in range(C)]
    if T == 0:
        out[0] = (0.0, [])
        return out
    ok = _allowed()
    start, own = _starts()
    lp = logp.copy()
    for b in banned:
        lp[:, ROLES.index(b)] = -np.inf
    first_ok = np.array([not r.startswith("I-") for r in ROLES])
    # the first word: a reference begins with it if it has one
    score = np.full((R, C), -np.inf)
    body0 = np.array([r[:2] in ("B-", "I-") for r in ROLES])
    c0 = body0.astype(int)
    score[np.arange(R), c0] = np.where(first_ok, lp[0], -np.inf)
    backs = []
    for t in range(1, T):
        new = np.full((R, C), -np.inf)
        back = np.zeros((R, C, 2), np.int64)
        for c in range(C):
            inc = start & (own[None, :] | (c == 0))  # (prev, cur)
            cand = np.where(ok, score[:, c][:, None], -np.inf)  # (prev, cur)
            for d in (0, 1):
                c2 = min(c + d, C - 1)
                m = np.where(inc == bool(d), cand, -np.inf)
                best_prev = m.argmax(axis=0)
                val = m[best_prev, np.arange(R)]
                better = val > new[:, c2]
                new[better, c2] = val[better]
                back[better, c2, 0] = best_prev[better]
                back[better, c2, 1] = c
        score = new + lp[t][:, None]
        backs.append(back)
    for n in range(C):
        j = int(score[:, n].argmax())
        if not np.isfinite(score[j, n]):
            continue
        total, path, c = float(score[j, n]), [j], n
        for back in reversed(backs):
            j, c = int(back[j, c, 0]), int(back[j, c, 1])
            path.append(j)
        out[n] = (total, [ROLES[i] for i in reversed(path)])
    return out


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
    from tabletop.torch_weights import load_torch_weights

    p = Path(path)
    if not p.is_file():
        raise AssetError(
            f"reader weights {str(p)!r} do not exist; train them with `tabletop train reader`"
        )
    doc = load_torch_weights(p, AssetError, "reader weights are written by `tabletop train reader`")
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
    """A side's or above's landmark: the thing's words (without a possessive ending, "the
    cube's right"), or the goal that narrows it."""
    if not goal.near and goal.primary.kind == "obj":
        return re.sub(r"'s?$", "", goal.primary.text)
    return goal


#: An image reference names a file: a path with a folder or an image file's extension.
_IMAGE_PATH = re.compile(r"[/\\~]|\.(?:png|jpe?g|bmp|webp|tiff?|gif)\b", re.IGNORECASE)
#: An image goal's whole text: one path to an image file, no quotes or brackets around it.
_IMAGE_FILE = re.compile(r"[^\s\"'()\[\]{};]+\.(?:png|jpe?g|bmp|webp|tiff?|gif)", re.IGNORECASE)
#: Code, not words: a call ("system("), a dotted name ("os.system"), a dunder, a statement.
_CODE = re.compile(r"\w\(|[A-Za-z_]\.[A-Za-z_]{2,}|__|[;={}<>\[\]\\]")

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


def _side_as_region(goals: list[Goal], relation: str) -> tuple[list[Goal], str]:
    """A side word tagged as a relation of a place's words that, with it, name a region of
    the table ("the left area", "the left side": 'left' of 'area') is that region: one goal,
    the place "left area", to go to. Other goals and relations are returned as they are."""
    from tabletop.reader.place_words import parse_region

    g = goals[0] if len(goals) == 1 else None
    if relation in _SIDES and g is not None and g.primary.kind == "area" and not g.near:
        words = re.findall(r"[a-z]+", g.primary.text.lower())
        if relation in words and parse_region(g.primary.text) is not None:
            return [g], "goto"  # the side word was tagged inside the place's words too
        merged = f"{relation} {g.primary.text}"
        if parse_region(merged) is not None:
            return [Goal(Part("area", merged))], "goto"
    return goals, relation


def _relation(scores: np.ndarray) -> str:
    """The step's relation: the most likely over its words (summed log-probabilities)."""
    return RELATIONS[int(np.argmax(scores.sum(axis=0)))]


#: How each relation is said, for messages.
_RELATION_SAID = {
    "goto": "going to a place",
    "between": "'between'",
    "backforth": "'back and forth between'",
    "above": "'above'",
    **{side: f"the {side} of a thing" for side in ("left", "right", "front", "behind")},
}


def _check(text: str, clause: str, relation: str, goals: list[Goal], times: int) -> None:
    """Refuse what the plan cannot honour, as the grammar does: a relation without the
    places it takes (or with more), a place named only by a pointing word, a side or above of
    something that is not a thing, too many repetitions."""
    from tabletop.reader.rules import _ARTICLES, MAX_REPEAT, POINTERS

    need = 2 if relation in ("between", "backforth") else 1
    if len(goals) != need:
        said = _RELATION_SAID.get(relation, relation)
        raise ParseError(
            text,
            clause,
            f"{said} takes {'two places' if need == 2 else 'one place'}; the request names "
            f"{len(goals)}" + (": join two places with 'then'" if need == 1 else ""),
        )
    for g in goals:
        for part in (g.primary, *g.near):
            if part.kind == "img":
                if not _IMAGE_PATH.search(part.text) or not _IMAGE_FILE.fullmatch(part.text):
                    raise ParseError(
                        text,
                        part.text,
                        "these words were read neither as a thing (a thing is named in words, "
                        "e.g. 'the red mug') nor as an image file (an image goal is an image "
                        "file's path, e.g. 'the image ./goal.png'; .png, .jpg, .jpeg, .bmp, "
                        ".webp, .tif, .gif)",
                    )
                continue
            if _CODE.search(part.text):
                raise ParseError(
                    text,
                    part.text,
                    "a place is named in words, not code (a call, a dotted name, a statement)",
                )
            words = _ARTICLES.sub("", part.text.lower() + " ").split()
            if not words or set(words) <= POINTERS:
                raise ParseError(text, part.text, "a word that points back names no place"
                                 if words else "the words name nothing")  # fmt: skip
    if relation in (*_SIDES, "above") and goals[0].primary.kind != "obj":
        raise ParseError(
            text, clause, f"'{relation}' is taken of a thing, not a {goals[0].primary.kind}"
        )
    if not 1 <= times <= MAX_REPEAT:
        raise ParseError(
            text, clause, f"repeat 1 to {MAX_REPEAT} times, not {times}", out_of_range=True
        )


#: Goals each relation takes (a ``motion`` step is read by the grammar; ``none`` is refused).
_NEEDS = {"between": 2, "backforth": 2, "motion": None, "none": None}


#: How much less likely [nats] than the tagger's own reading a joint reading may be: beyond
#: it, the step keeps the tagger's roles and relation (and is refused if they disagree).
#: Picked on generated requests of the validation pools (``tabletop train reader`` prints
#: plans right at each), never on an evaluation suite.
JOINT_MARGIN = 6.0
#: A word is sure of its relation at this probability; two relations each sure on this many
#: words of one step are two requests run together (:func:`_one_relation`).
SURE_RELATION, SURE_WORDS = 0.9, 2


def _keeps_what_it_names(text: str, words: list[str], own: list[str], chosen: list[str]) -> None:
    """Refuse a re-cut of a step's roles (:func:`_joint`) that leaves out a word naming a
    thing, a colour or a sound the tagger's own reading put inside a reference ("go to the
    mug in front of the duck" is no request to go in front of the duck): what a person names
    is never dropped silently."""
    from tabletop.reader.spelling import name_words

    names = name_words()
    lost = [
        w
        for w, a, b in zip(words, own, chosen, strict=True)
        if a != "O" and b == "O" and w.strip(",.;:!?\"'").lower() in names
    ]
    if lost:
        raise ParseError(
            text, " ".join(words), f"reading it as one request would leave out {lost[0]!r}"
        )


def _one_relation(
    text: str, clause: str, rel_logp: np.ndarray, words=None, rules=None, robot: str = "arm"
) -> None:
    """Refuse a step whose words are sure of two different relations (:data:`SURE_RELATION`
    on :data:`SURE_WORDS` words each): two requests run together without a joining word the
    tagger read ("move in front of the duck, then to the right of it"). Going somewhere is
    no second request beside another relation: the way there is said with it.

    A ``motion`` is read by the grammar (``rules(clause, robot)``): words sure of it that the
    grammar does not read as a motion ask for none, and are no second request (a way of
    saying "go" that the tagger took for a motion)."""
    sure = np.exp(rel_logp.max(axis=1)) >= SURE_RELATION
    best = rel_logp.argmax(axis=1)
    held = {RELATIONS[r] for r in np.unique(best[sure]) if (best[sure] == r).sum() >= SURE_WORDS}
    held -= {"none"}
    if len(held) > 1 and "motion" in held and words is not None and rules is not None:
        m = RELATIONS.index("motion")
        span = " ".join(w for w, b, s in zip(words, best, sure, strict=True) if s and b == m)
        try:
            read = rules(span, robot)
        except ParseError:
            read = ()
        if not any(isinstance(st.action, MOTIONS) for st in read):
            held.discard("motion")
    if len(held) > 1:  # going is how the other relation is reached, no second request
        held.discard("goto")
    if len(held) > 1:
        raise ParseError(
            text,
            clause,
            f"it asks for {' and '.join(sorted(held))} at once: join two requests with 'then'",
        )


def _joint(role_logp: np.ndarray, rel_logp: np.ndarray, margin: float = JOINT_MARGIN
           ) -> tuple[list[str], str]:  # fmt: skip
    """A step's roles and relation read together: the relation and the roles that name as
    many goals as it takes, most likely jointly (a relation's score is its words' summed
    log-probabilities). So a reference the tagger split in two, or two it joined, is cut the
    way the step's relation allows, instead of being refused, when that reading is at most
    ``margin`` nats less likely than the tagger's own (its best roles and relation apart)."""
    counts = goal_counts(role_logp)
    free = max(counts, key=lambda c: c[0])
    rel_sum = rel_logp.sum(axis=0)
    own = (float(rel_sum.max() + free[0]), free[1], RELATIONS[int(np.argmax(rel_sum))])
    best = (-np.inf, free[1], own[2])
    for r, name in enumerate(RELATIONS):
        need = _NEEDS.get(name, 1)
        score, roles = free if need is None else counts[need]
        if rel_sum[r] + score > best[0]:
            best = (float(rel_sum[r] + score), roles, name)
    chosen = best if best[0] >= own[0] - margin else own
    return chosen[1], chosen[2]


def _relation_before_landmark(text: str, words: list[str], roles: list[str], relation: str
                              ) -> None:  # fmt: skip
    """Refuse a side or "above" said after the thing it would be taken of, between it and a
    thing near it ("the mug which is tucked away behind the duck", read as behind the mug
    near the duck): the relation picks the first thing by where it stands, which no reading
    honours. ParseError naming the thing."""
    from tabletop.reader.rules import _ABOVE
    from tabletop.reader.rules import _SIDES as _SIDE_RX
    from tabletop.relations import relation_by_side

    def starts_relation(rest: str) -> bool:
        """Whether ``rest`` starts with the step's own relation, said before a thing ("behind
        the duck"; not "the duck's left", said after it)."""
        if relation == "above":
            return bool(_ABOVE.match(rest))
        return any(side == relation and rx.match(rest) for side, rx in _SIDE_RX)

    first = next((i for i, r in enumerate(roles) if r != "O"), None)
    if first is None:
        return
    end = next((i for i in range(first, len(roles)) if roles[i] == "O"), len(roles))
    near = next((i for i in range(end, len(roles)) if roles[i].startswith("B-N")), None)
    if near is None:
        return
    for k in range(end, near):
        if starts_relation(" ".join(words[k:]).lower()):
            said = relation_by_side(relation).wording if relation in _SIDES else "above"
            thing = " ".join(words[first:end])
            raise ParseError(
                text,
                thing,
                f"{thing!r} is picked by where it stands ({said!r} another thing), which "
                "is not read: ask for the place, 'go to the left of the duck', or the thing "
                "near another, 'go to the mug near the duck'",
            )


def _two_at_and(words: list[str], roles: list[str]) -> list[Goal] | None:
    """The two things of a "between" whose descriptions the tagger cut into more pieces
    ("between the prism which is sort of dark red and the brick with the studs on top"): each
    side of the one "and" among them is one thing's words, where every piece names an object;
    None otherwise."""
    refs = [i for i, r in enumerate(roles) if r != "O"]
    if not refs or any(not roles[i].endswith("OBJ") for i in refs):
        return None
    first, last = refs[0], refs[-1]
    joins = [
        i
        for i in range(first, last)
        if roles[i] == "O" and words[i].lower().strip(",") in ("and", "&")
    ]
    if len(joins) != 1:
        return None
    a, b = " ".join(words[first : joins[0]]), " ".join(words[joins[0] + 1 : last + 1])
    return [Goal(Part("obj", _bare(a))), Goal(Part("obj", _bare(b)))]


#: Words that only join two references: "A and B", "A & B", "A plus B".
_JOIN_ONLY = re.compile(r"^(?:,?\s*(?:and|&|plus)\s*)+$", re.IGNORECASE)


def _between_said(text: str, clause: str, words: list[str], roles: list[str]) -> None:
    """Refuse a "between" that no word says: two things joined by "and" straight after the
    verb ("go to the mug and the duck") ask for both, not for the point between them; the
    tagger reads "between" from the "and" alone. ParseError naming the clause."""
    refs = [i for i, r in enumerate(roles) if r != "O"]
    if not refs or "," in clause:  # a list of things is refused as one, by name
        return
    from tabletop.reader.rules import is_verb_phrase

    lead = " ".join(words[: refs[0]])
    gaps = [" ".join(words[a + 1 : b]) for a, b in itertools.pairwise(refs) if b > a + 1]
    if is_verb_phrase(lead) and len(gaps) == 1 and _JOIN_ONLY.match(gaps[0]):
        raise ParseError(
            text,
            clause,
            "two things joined by 'and' with nothing saying where to go among them: say "
            "'between A and B' for the point between them, or 'A, then B' to go to each in "
            "turn",
        )


#: Words that join the two goals of a "between" or a "back and forth": "A and B", "from A to
#: B", "A or B", "A, B", "A as well as B" (space-separated).
_COORDINATORS = frozenset("and & plus n to from or as till until , + vs versus".split())


def _coordinated(words: list[str], roles: list[str]) -> bool:
    """Whether a word joins the step's first two goals: among the plain words between the
    end of the first goal's own words and the start of the second's (references as
    :func:`_spans` cuts them; a goal's constraints are not goals). "the mug rubbing shoulders
    with the duck" joins none: one thing said to be near another, not two things to go
    between."""
    runs: list[tuple[int, int, str]] = []  # (start, end, body) of each reference
    for i, r in enumerate(roles):
        body = r[2:] if r[:2] in ("B-", "I-") else ""
        if body and runs and runs[-1][1] == i and runs[-1][2] == body:
            runs[-1] = (runs[-1][0], i + 1, body)
        elif body:
            runs.append((i, i + 1, body))
    goals = [(a, b) for a, b, body in runs if not body.startswith("N")]
    if len(goals) < 2:
        return True
    for i in range(goals[0][1], goals[1][0]):
        w = words[i].lower()
        if roles[i] == "O" and (w.strip(",.;:") in _COORDINATORS or w.endswith(",")):
            return True
    return False


def decode(text: str, words: list[str], roles: list[str], relations, robot: str,
           rules, role_logp: np.ndarray | None = None,
           margin: float = JOINT_MARGIN) -> tuple[Step, ...]:  # fmt: skip
    """The plan of tagged ``words``; ``relations`` are each word's relation label or its
    (n_words, len(RELATIONS)) log-probabilities; ``rules(clause, robot)`` reads a ``motion``
    step. With ``role_logp`` (the roles' (n_words, len(ROLES)) log-probabilities), each step's
    roles and relation are read jointly (:func:`_joint`); ``roles`` then only cut the steps.

    Raises:
        ParseError: a step has no reference, or asks what the arm does not do.
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
        if role_logp is not None:
            step_roles, relation = _joint(role_logp[idx], relations[idx], margin)
            _keeps_what_it_names(text, [words[i] for i in idx], [roles[i] for i in idx],
                                 step_roles)  # fmt: skip
        else:
            step_roles, relation = [roles[i] for i in idx], _relation(relations[idx])
        _one_relation(text, clause, relations[idx], [words[i] for i in idx], rules, robot)
        times = _count([words[i] for i, r in zip(idx, step_roles, strict=True) if r == "REP"])
        said = _said_times([words[i] for i in idx])
        if said is not None and (times == 1 or said > MAX_TIMES_SAID):
            times = said  # "N times" read inside a reference still counts
        goals = _goals(_spans([words[i] for i in idx], step_roles))
        if relation == "none":
            from tabletop.reader.rules import negations

            if negated := negations(clause):  # "the mug that is not red": say why, by name
                raise ParseError(text, negated[0], "the robot cannot honour a negated goal")
            raise ParseError(
                text,
                clause,
                "the robot goes to places (a thing, a sound, a place on the table, between two "
                "things, a side of one or above it); this step asks something else, such as "
                "an action on a thing, a condition or a question: e.g. 'go to the red mug'",
            )
        if relation == "motion":
            steps.extend(rules(clause, robot))
            continue
        if not goals:
            raise ParseError(text, clause, "the step names nothing to go to")
        goals, relation = _side_as_region(goals, relation)
        if relation == "between" and len(goals) == 2:
            step_words = [words[i] for i in idx]
            if not _coordinated(step_words, step_roles):  # the second thing narrows the first
                a, b = goals
                goals, relation = [Goal(a.primary, (*a.near, b.primary, *b.near))], "goto"
        if relation in ("between", "backforth") and len(goals) > 2:
            goals = _two_at_and([words[i] for i in idx], step_roles) or goals
        _check(text, clause, relation, goals, times)
        if relation == "between":
            _between_said(text, clause, [words[i] for i in idx], step_roles)
            action = Between(goals[0], goals[1])
        elif relation == "backforth":
            action = BackAndForth(goals[0], goals[1])
        elif relation in _SIDES:
            _relation_before_landmark(text, [words[i] for i in idx], step_roles, relation)
            action = Side(relation, _landmark(goals[0]))
        elif relation == "above":
            _relation_before_landmark(text, [words[i] for i in idx], step_roles, relation)
            action = Above(_landmark(goals[0]))
        else:
            action = GoTo(goals[0])
        steps.append(Step(action, times, clause))
    if not steps:
        raise ParseError(text, text, "the request names nothing to go to")
    return tuple(steps)
