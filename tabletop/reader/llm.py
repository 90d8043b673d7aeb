"""The ``llm`` reader: any OpenAI-compatible endpoint asked for the typed plan as structured
output, and the answer validated before anything uses it.

The endpoint gets a short description of the plan (:data:`PLAN_SCHEMA`, a JSON schema sent as
``response_format``, for endpoints that constrain decoding to it) and the request. Its reply
must be one JSON object ``{"steps": [...]}``; :func:`plan_from_json` turns it into the same
values the other readers make (:mod:`tabletop.reader.plan`) or raises :class:`ParseError`
naming what is wrong. A model's free text is never run.
"""

from __future__ import annotations

import json
import math
import re

from tabletop.errors import ConfigError
from tabletop.reader.errors import ParseError
from tabletop.reader.llm_client import LLMConfig, chat
from tabletop.reader.plan import (
    PART_KINDS,
    Above,
    BackAndForth,
    Between,
    Compass,
    Goal,
    GoTo,
    Part,
    Reading,
    Side,
    Step,
)
from tabletop.reader.rules import (
    MAX_DISTANCE_M,
    MAX_REPEAT,
    refuse_negated,
    refuse_nested_relation,
    refuse_non_words,
)
from tabletop.reader.spelling import default_speller

__all__ = ["PLAN_SCHEMA", "LLMReader", "plan_from_json"]

_PART = {
    "type": "object",
    "properties": {"kind": {"enum": list(PART_KINDS)}, "text": {"type": "string"}},
    "required": ["kind", "text"],
}
_GOAL = {
    "type": "object",
    "properties": {"primary": _PART, "near": {"type": "array", "items": _PART}},
    "required": ["primary"],
}
ACTIONS = ("goto", "between", "side", "above", "backforth", "compass")
SIDES = ("left", "right", "front", "behind")
DIRECTIONS = ("north", "south", "east", "west")
#: The typed form the endpoint is asked for (JSON schema).
PLAN_SCHEMA = {
    "type": "object",
    "properties": {
        "steps": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "action": {"enum": list(ACTIONS)},
                    "times": {"type": "integer", "minimum": 1},
                    "goal": _GOAL,
                    "a": _GOAL,
                    "b": _GOAL,
                    "side": {"enum": list(SIDES)},
                    "direction": {"enum": list(DIRECTIONS)},
                    "distance_m": {"type": "number"},
                },
                "required": ["action"],
            },
        }
    },
    "required": ["steps"],
}
SYSTEM = (
    "You read a person's request to a robot arm above a table and answer with one JSON object "
    "that follows this schema: " + json.dumps(PLAN_SCHEMA) + ". Each step's action: goto (its "
    "'goal'), between ('a' and 'b'), side (a 'side' of 'goal': left, right, front = the far "
    "side from the robot, behind = the robot's side), above ('goal'), backforth ('a' and 'b'), "
    "compass ('direction' and 'distance_m' in metres). A goal is a 'primary' part and 'near' "
    "parts that narrow it; a part's kind is obj (a thing), sound (something heard), area (a "
    "place on the table) or img (an image path), its text the person's own words for it, "
    "without 'the sound of' or 'where you heard'. 'times' repeats a step. Answer only JSON."
)


def _part(d, where: str) -> Part:
    if not isinstance(d, dict) or d.get("kind") not in PART_KINDS:
        raise ValueError(f"{where}: a part needs a kind in {list(PART_KINDS)}")
    text = d.get("text")
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"{where}: a part needs its words ('text')")
    return Part(d["kind"], " ".join(text.split()))


def _goal(d, where: str) -> Goal:
    if not isinstance(d, dict):
        raise ValueError(f"{where}: missing")
    near = d.get("near") or []
    if not isinstance(near, list):
        raise ValueError(f"{where}.near: must be a list of parts")
    parts = tuple(_part(p, f"{where}.near[{i}]") for i, p in enumerate(near))
    return Goal(_part(d.get("primary"), f"{where}.primary"), parts)


def _step(d, i: int, text: str) -> Step:
    where = f"steps[{i}]"
    if not isinstance(d, dict) or d.get("action") not in ACTIONS:
        raise ValueError(f"{where}: action must be one of {list(ACTIONS)}")
    times = d.get("times", 1)
    if not isinstance(times, int) or isinstance(times, bool) or not 1 <= times <= MAX_REPEAT:
        raise ValueError(f"{where}.times: an integer from 1 to {MAX_REPEAT}")
    a = d["action"]
    if a == "goto":
        action = GoTo(_goal(d.get("goal"), f"{where}.goal"))
    elif a in ("between", "backforth"):
        two = (_goal(d.get("a"), f"{where}.a"), _goal(d.get("b"), f"{where}.b"))
        action = Between(*two) if a == "between" else BackAndForth(*two)
    elif a == "side":
        if d.get("side") not in SIDES:
            raise ValueError(f"{where}.side: one of {list(SIDES)}")
        g = _goal(d.get("goal"), f"{where}.goal")
        action = Side(d["side"], g.primary.text if not g.near and g.primary.kind == "obj" else g)
    elif a == "above":
        g = _goal(d.get("goal"), f"{where}.goal")
        action = Above(g.primary.text if not g.near and g.primary.kind == "obj" else g)
    else:
        dist = d.get("distance_m")
        if d.get("direction") not in DIRECTIONS:
            raise ValueError(f"{where}.direction: one of {list(DIRECTIONS)}")
        if not isinstance(dist, int | float) or not (0 < dist <= MAX_DISTANCE_M):
            raise ValueError(f"{where}.distance_m: a number of metres in (0, {MAX_DISTANCE_M}]")
        if not math.isfinite(dist):
            raise ValueError(f"{where}.distance_m: must be finite")
        action = Compass(d["direction"], float(dist))
    return Step(action, times, text)


def plan_from_json(reply: str, text: str) -> tuple[Step, ...]:
    """The plan in an endpoint's ``reply`` to ``text`` (:class:`ParseError` naming the
    problem: no JSON object, a wrong field, an empty plan)."""
    m = re.search(r"\{.*\}", reply or "", re.DOTALL)
    if m is None:
        raise ParseError(text, text, "the model's answer holds no JSON object")
    try:
        doc = json.loads(m.group(0))
        steps = doc.get("steps") if isinstance(doc, dict) else None
        if not isinstance(steps, list) or not steps:
            raise ValueError("the answer has no steps")
        return tuple(_step(s, i, text) for i, s in enumerate(steps))
    except (json.JSONDecodeError, ValueError, ConfigError) as e:
        raise ParseError(text, text, f"the model's plan is not valid: {e}") from None


class LLMReader:
    """Reads requests by asking an endpoint (:class:`~tabletop.reader.llm_client.LLMConfig`;
    from the environment when not given). References are corrected as the default reader
    corrects them."""

    name = "llm"

    def __init__(self, config: LLMConfig | None = None) -> None:
        self.config = config or LLMConfig.from_env()

    def reference(self, kind: str, text: str):
        if kind not in PART_KINDS or kind == "img":
            raise ConfigError(f"unknown reference kind {kind!r}; valid: obj, sound, area")
        if not isinstance(text, str):
            raise ConfigError(f"{kind}= must be a string, got {type(text).__name__}")
        text = default_speller().correct(text)[0]
        refuse_negated(text)
        if kind == "area":
            from tabletop.reader.places import PlaceReader

            return PlaceReader(learned=True).read(text)
        return text

    def understand(self, text: str, robot: str = "arm") -> Reading:
        if not isinstance(text, str) or not text.strip():
            raise ConfigError("an instruction must be a non-empty string")
        if robot != "arm":
            raise ConfigError(f"the llm reader reads the arm's requests only, not {robot!r}")
        refuse_non_words(text)
        refuse_nested_relation(text)  # the plan's relations are taken of things only
        messages = [{"role": "system", "content": SYSTEM}, {"role": "user", "content": text}]
        fmt = {"type": "json_schema", "json_schema": {"name": "plan", "schema": PLAN_SCHEMA}}
        steps = plan_from_json(chat(messages, self.config, response_format=fmt), text)
        return Reading(text, text, steps, (), (), self.name)
