"""The words that name a place on the table: which phrases are a region of the table's own
geometry ("the left side of the table", "the far right corner", "the middle"), and what a place
named after its contents is named after ("the area around the tray" -> "tray").

Read at query time only (a map holds nothing this module computes); the regions themselves
are computed in :mod:`tabletop.mapping.table_regions`.

Geometric phrasings (case and the articles "the"/"a" aside; "table" may be left out):

- lateral: "left", "left-hand", "lefthand", "leftmost", "port" / "right", "right-hand",
  "righthand", "rightmost", "starboard" (the outer thirds of the table's width);
- depth: "front", "frontmost", "forward", "far", "farthest", "furthest", "opposite", "far side",
  "far end", "away from the robot", "opposite the robot" (the half away from the robot) /
  "back", "rearmost", "near", "nearest", "closest", "rear", "near side", "close to the
  robot", "next to the robot", "by the robot", "the robot's side" / "end" / "half", "where
  the robot stands" / "is" / "sits" (the half nearest the robot; "arm" or "base" may stand
  for "robot", and so may "the arm's base" or "you": the robot is the one asked, so "the half
  closest to you", "your side", "your end", "the part you are at" are its side, and "the end
  farthest from where you stand" the other); "in front of the robot" is its forward half,
  the front, but "right", "just", "directly" or "immediately in front of the robot" is the
  strip by it;
- "side", "part", "half", "end", "edge", "margin", "border", "corner", "area", "wing",
  "flank", "quarter", "strip", "patch", "sector" and the like name no direction ("the right
  wing" is the right side), nor do "away", "over", "along", "towards", "most", "extreme" or
  "third" beside a direction ("the part farthest away", "over on the left", "the stretch
  along the back", "the right-most third"), nor "there", "here" or "please" ("the right side
  over there"), nor "off" ("the part off to the right"), nor "whole" or "entire" ("the middle
  of the whole table");
- "center"/"centre"/"central"/"middle"/"mid"/"midpoint"/"midway"/"halfway"/"heart"/"core"/
  "centremost"/"innermost" alone: the middle third in both directions; with a lateral or a
  depth word it is the middle of the other direction ("the middle of the left side"); "very",
  "dead", "exact", "smack", "slap", "bang", "dab", "plumb", "squarely" and "right in" may
  stress it ("right in the middle" is no right side, "slap-bang in the centre" no sound);
- corners: a lateral and a depth word together ("the far right corner", "front left");
- the robot's own sides are the table's: "the robot's right", "the arm's left-hand side",
  "your left", "to the right of the robot"; and words that name the robot's viewpoint name
  nothing more ("the left-hand end as the robot sees it", "seen from the arm", "from your
  point of view");
- "beyond" or "past the middle" is the far half, "short of" or "this side of the middle" the
  near half; "the robot's own end", "where the arm is mounted" (fixed, bolted, placed, ...) are
  the robot's.
"""

from __future__ import annotations

import re

from tabletop.mapping.table_regions import TableRegion

__all__ = [
    "area_subject",
    "directions",
    "ground_phrases",
    "ground_preposition",
    "opposite_directions",
    "parse_region",
    "region_on_ground",
]

_LEFT = r"left\s*hand|leftmost|left|port"
_RIGHT = r"right\s*hand|rightmost|right|starboard"
# Longer phrases first: the alternation takes the first that matches.
_ROBOT = r"(?:(?:the\s+)?(?:(?:robot|arm)(?:\s+base)?|base)|you|yourself)"
#: How the robot is set where it stands: "where the arm is mounted".
_SET = r"(?:mounted|fixed|attached|bolted|clamped|placed|located|positioned|installed|based)"
#: Where the robot is: "the robot", "you", "where you are", "where the arm stands".
_ROBOT_AT = rf"(?:where\s+)?{_ROBOT}\s+(?:is|are|stands?|sits?|(?:is|are)\s+{_SET})|{_ROBOT}"
#: The robot's own (side): "your side", "the arm's end" ("'s" is dropped before reading).
_ROBOTS = rf"(?:{_ROBOT}|your|yours)"
_FAR = (
    rf"across\s+(?:the\s+\w+\s+)?from\s+(?:{_ROBOT_AT})|"
    rf"(?:far(?:thest|ther)?|furthest|further)(?:\s+(?:end|side|part))?\s+(?:away\s+)?from\s+"
    rf"(?:{_ROBOT_AT})|away\s+from\s+(?:{_ROBOT_AT})|opposite\s+(?:to\s+|from\s+)?{_ROBOT}|"
    r"far\s+(?:side|end)|front\s*most|front|forward|far(?:thest|ther)?|furthest|further|"
    r"opposite"
)
_NEAR = (
    rf"(?:close(?:st)?|near(?:est)?|next)\s+(?:to\s+)?{_ROBOT}|by\s+{_ROBOT}|"
    rf"(?:on\s+)?{_ROBOTS}\s+(?:own\s+)?(?:side|end|half|edge)|"
    rf"(?:by\s+)?(?:where|that)\s+{_ROBOT}\s+(?:stands?|is|are|sits?)(?:\s+{_SET})?|"
    rf"{_ROBOT}\s+(?:are|is|stand|stands|sit|sits)\s+(?:at|by|on|beside)|"
    r"near\s+(?:side|end)|(?:back|rear|hind)\s*most|back|rear|near(?:est|er)?|closest"
)
_MID = (
    r"cent(?:er|re)\s*most|middle\s*most|mid\s*most|innermost|center|centre|central|middle|"
    r"mid\s*point|midway|halfway|heart|core|mid"
)
# "right in front of the robot" is the strip just ahead of it, by the robot; "in front of the
# robot" alone is the robot's forward direction, the front (far) half.
_JUST_AHEAD = re.compile(rf" (?:right|just|directly|immediately) in front of {_ROBOT} ")
_AHEAD = re.compile(rf" (?:out )?in front of {_ROBOT} ")
_STRESSED_MID = re.compile(rf" right (?=(?:in|at) (?:the )?(?:(?:very|dead|exact) )?(?:{_MID}) )")
_ROBOTS_SIDE = re.compile(rf" (?:{_ROBOT}|your) (?=(?:{_LEFT}|{_RIGHT}) )")
# "to the right of the robot" is the robot's right, the table's right
_OF_ROBOT = re.compile(rf" ({_LEFT}|{_RIGHT}) (?:hand )?(?:side )?of {_ROBOT} ")
# the robot's viewpoint is the one the sides are named from anyway: "as the robot sees it",
# "seen from the arm", "from your point of view"
_VIEWPOINT = re.compile(
    rf" (?:(?:as|how) (?:{_ROBOT}) (?:sees?|views?|looks? at|faces?)(?: it| them| things)?|"
    rf"(?:as )?(?:seen|viewed) (?:by|from) (?:{_ROBOT})|"
    rf"from (?:{_ROBOT}|your) (?:point of view|perspective|viewpoint|view)) "
)
# past the middle, away from the robot, is the far half; short of it the near half
_BEYOND_MID = re.compile(rf" (?:beyond|past) (?:the )?(?:{_MID}) ")
_SHORT_OF_MID = re.compile(rf" (?:short of|this side of|before) (?:the )?(?:{_MID}) ")
#: Words a geometric phrase may hold beside the place words (space-separated).
_FILLER = (
    "the a of on at in to table tabletop side part half corner edge area region zone end and "
    "top surface portion section space bit s very dead exact exactly point spot wing flank "
    "quarter strip stretch patch segment sector slice chunk away over toward towards most "
    "extreme outer outermost third margin border fringe along smack slap bang dab plumb "
    "squarely just row lip up it all there here please off whole entire"
)


#: Filler words that name the table itself (a region "of the table top"): kept as the ground's
#: words by :func:`region_on_ground`, which reads what a region is named on.
_SURFACE_FILLER = frozenset({"table", "tabletop", "top", "surface"})


def _geometry(text: str) -> tuple[dict[str, str], list[str]] | None:
    """The geometric words ``text`` holds ({"depth": "far", ...}) and its other words in order,
    or None when it names two opposite directions ("left ... right")."""
    found, rest, clash = _directions(text)
    return None if clash else (found, rest)


def directions(text: str) -> dict[str, str]:
    """The geometric words ``text`` names ({"depth": "far", "lateral": "left"}; {} for none)."""
    return _directions(text)[0]


def opposite_directions(text: str) -> tuple[str, str] | None:
    """The two opposite directions ``text`` names ("left", "right"; "far", "near"), which no
    one region lies in; None when it names none such."""
    return _directions(text)[2]


def _directions(text: str) -> tuple[dict[str, str], list[str], tuple[str, str] | None]:
    """(the geometric words ``text`` holds, its other words, the first two opposite
    directions it names or None)."""
    t = " " + re.sub(r"[^a-z ]", " ", str(text).lower().replace("'s", " ")) + " "
    t = re.sub(r"\s+", " ", t)
    # a direction made an adjective or hedged keeps its direction: "lefty", "right-ish"
    t = re.sub(r" (left|right)(?:y|ie)(?= )", r" \1", t)
    t = re.sub(rf" ({_LEFT}|{_RIGHT}|{_MID}|front|back|far|near) ?ish(?= )", r" \1", t)
    t = _JUST_AHEAD.sub(" near the robot ", t)
    t = _AHEAD.sub(" front ", t)
    t = _STRESSED_MID.sub(" ", t)  # "right in the middle": no right side
    t = _VIEWPOINT.sub(" ", t)
    t = _ROBOTS_SIDE.sub(" ", t)  # "the robot's right" is the table's right
    t = _OF_ROBOT.sub(r" \1 ", t)
    t = _BEYOND_MID.sub(" far ", t)
    t = _SHORT_OF_MID.sub(" near ", t)
    found: dict[str, str] = {}
    for key, value, pattern in (
        ("depth", "far", _FAR),
        ("depth", "near", _NEAR),
        ("lateral", "left", _LEFT),
        ("lateral", "right", _RIGHT),
        ("mid", "middle", _MID),
    ):
        rx = re.compile(rf" (?:{pattern}) ")
        while rx.search(t):
            if key in found and found[key] != value:
                return found, t.split(), (found[key], value)  # "left ... right"
            found[key] = value
            t = rx.sub(" ", t, count=1)
    return found, t.split(), None


def _region(found: dict[str, str], text: str) -> TableRegion:
    lateral, depth = found.get("lateral"), found.get("depth")
    if "mid" in found:
        if lateral is None and depth is None:
            lateral = depth = "middle"
        elif lateral is None:
            lateral = "middle"
        elif depth is None:
            depth = "middle"
    return TableRegion(lateral, depth, str(text))


def parse_region(text: str) -> TableRegion | None:
    """The geometric region ``text`` names, or None when it is not (only) a place on the table
    (see the module docstring for the phrasings)."""
    read = _geometry(text)
    if read is None:
        return None
    found, rest = read
    filler = set(_FILLER.split())
    if not found or any(w not in filler for w in rest):
        return None  # nothing geometric, or other words ("the tray area")
    return _region(found, text)


def region_on_ground(text: str) -> tuple[TableRegion, str] | None:
    """A geometric region named on something the grammar does not take for the table, and
    that something (the ground): "the far end of the workbench" -> (the far half, "workbench"),
    "the left of the garden" -> (the left third, "garden"). None when ``text`` names no
    direction, or names nothing besides the region (:func:`parse_region` reads those).

    Whether the ground is the surface the map holds is not decided here: the place reader's
    learned ground classifier decides it by the ground's meaning, not by a list.
    """
    read = _geometry(text)
    if read is None or not read[0]:
        return None
    found, rest = read
    filler = set(_FILLER.split()) - _SURFACE_FILLER
    ground = [w for w in rest if w not in filler]
    if not ground or all(w in _SURFACE_FILLER for w in ground):
        return None
    return _region(found, text), " ".join(ground)


#: Words that wrap an object into a place: "the area around the tray", "the spot by the mug"
#: (space-separated).
_PLACE_WORDS = (
    "the a an area around near by next to beside spot place region zone space part side of "
    "close where is are stands sits lies over there here please"
)


def area_subject(text: str) -> str | None:
    """What a place named by its contents is named after: "the area around the tray" ->
    "tray", "the spot by the blue mug" -> "blue mug"; None when ``text`` holds only place
    words or is a geometric region (:func:`parse_region`)."""
    if parse_region(text) is not None:
        return None
    words = re.sub(r"[^a-z ]", " ", str(text).lower()).split()
    place = set(_PLACE_WORDS.split())
    rest = [w for w in words if w not in place]
    return " ".join(rest) or None


#: Words that end the noun phrase a region is named on ("the left of the garden *by* the
#: shed"): prepositions, relative words and the robot's own words (space-separated).
_GROUND_ENDS = frozenset(
    "of on in at by from to near with for toward towards past beyond over under along across "
    "off up down around round where which that who whose as than nearest closest furthest "
    "farthest and or but if so".split()
)
_GROUND_ARTICLES = frozenset("the a an my our your its this that these those their his her".split())
_GROUND_AFTER = re.compile(r"\b(?:of|on|in|across|at)\b")


def ground_preposition(text: str) -> re.Match | None:
    """The first "of", "on", "in", "across" or "at" of ``text`` (lower-cased), after which a
    region's ground may be named; None where it has none."""
    return _GROUND_AFTER.search(str(text).lower())


def ground_phrases(text: str) -> list[str]:
    """The noun phrases a region of ``text`` is named on: each phrase after "of", "on", "in",
    "across" or "at", without its article, up to the next preposition, relative word, robot
    word or direction ("the far corner of the room" -> ["room"]; "the left end of the desk by
    you" -> ["desk"]; "the bit furthest from me" -> []). A phrase of place words alone ("the
    end of the left side") is none; the table's own words are kept ("the table")."""
    t = re.sub(r"[,;:()]", " , ", str(text).lower().replace("'s", " "))
    t = re.sub(r"[^a-z, ]", " ", t)
    filler = set(_FILLER.split()) - _SURFACE_FILLER
    out = []
    for m in _GROUND_AFTER.finditer(t):
        words = []
        for w in t[m.end() :].split():
            if w in _GROUND_ARTICLES and not words:
                continue
            robot = re.fullmatch(_ROBOTS, w)
            if w == "," or w in _GROUND_ENDS or robot or _directions(f" {w} ")[0]:
                break
            words.append(w)
        if any(w not in filler for w in words) and (g := " ".join(words)) not in out:
            out.append(g)
    return out
