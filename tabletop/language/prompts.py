"""The few-shot prompt for an LLM backend, in the style of the paper's prompts (an instruction
as a comment, then the robot code), written for the table-top robot API.

The examples use objects, sounds and pictures that are not in the shipped scenes, so a model
has to carry the pattern over rather than copy an answer.
"""

from __future__ import annotations

from dataclasses import dataclass

from tabletop.robot.primitives import primitives_of

__all__ = [
    "ARM_PROMPT",
    "EXAMPLES",
    "MOBILE_EXAMPLES",
    "MOBILE_PROMPT",
    "SYSTEM_PROMPT",
    "PromptParts",
    "api_list",
    "prompt_messages",
    "prompt_text",
    "system_prompt",
]

_PREAMBLE = """\
You write Python for a robot arm above a table. The arm has a map of the table built from its
wrist camera and microphone. Answer with code only: no explanations, no imports, no functions,
no if or while. Use only the object `robot`, numbers, strings, variables, + - * /, tuples and
lists, and `for _ in range(n)` loops. Positions are 3D points in metres in the robot's base
frame: north = +x (away from the robot), west = left = +y, east = right = -y, z up.
"""

_CONVENTIONS = """\
obj= is an object description, sound= a sound description, area= a region of the table
("left side of the table", "center of the table", "tray area"), img= an image from
robot.load_image. Multiply heatmaps to combine them: the goal the robot should reach gets
get_major_map, every goal that only narrows it down ("near", "next to", "where you heard")
gets get_map. A landmark (name, a, b) is an object description or a heatmap: "between A and
B" is robot.move_in_between(A, B) with an object's name, or the goal's heatmap for any other
goal.
"""


_MOBILE_PREAMBLE = """\
You write Python for a wheeled robot base in a room. The base has a map of the room built from
its camera and microphone. Answer with code only: no explanations, no imports, no functions,
no if or while. Use only the object `robot`, numbers, strings, variables, + - * /, tuples and
lists, and `for _ in range(n)` loops. Positions are 3D points in metres in the room's frame
(z up, the floor at z = 0); the base drives on the floor to the point's x, y. "Left of",
"in front of" a landmark are in the base's own frame: to its left, further along its heading.
"""

_MOBILE_CONVENTIONS = """\
obj= is an object description, sound= a sound description, area= a place named by what is
there ("the area around the sofa"), img= an image from robot.load_image. Multiply heatmaps to
combine them: the goal gets get_major_map, every goal that only narrows it down ("near",
"where you heard") gets get_map. A landmark (name, a, b) is an object description or a
heatmap.
"""


@dataclass(frozen=True)
class PromptParts:
    """What a robot's prompt says besides its API list (an embodiment's ``prompt``,
    :mod:`tabletop.embodiments`): the rules before the list, the conventions after it, and the
    few-shot examples ((instruction, code) pairs)."""

    preamble: str
    conventions: str
    examples: tuple[tuple[str, str], ...]


def _parts(robot: str) -> PromptParts:
    from tabletop.embodiments import embodiment

    return embodiment(robot).load("prompt")  # names the valid robots


def api_list(robot: str = "arm") -> str:
    """The prompt's API list for ``robot`` (an :mod:`~tabletop.embodiments` name), one line
    per declared primitive that robot has (:data:`PRIMITIVES`)."""
    width = 40
    return "".join(f"{p.call:<{width - 1}} -> {p.summary}\n" for p in primitives_of(robot))


def system_prompt(robot: str = "arm") -> str:
    """The system message for ``robot``: the rules, the API list generated from the
    declaration, conventions."""
    parts = _parts(robot)
    return f"{parts.preamble}\n{api_list(robot)}\n{parts.conventions}"


#: (instruction, code) pairs, in the order they are shown to the model.
EXAMPLES: tuple[tuple[str, str], ...] = (
    (
        "go to the green bowl",
        'robot.move_to_object("green bowl")',
    ),
    (
        "move to the cup next to the sound of a kettle whistling",
        'obj_map = robot.get_major_map(obj="cup")\n'
        'sound_map = robot.get_map(sound="kettle whistling")\n'
        "fuse_map = obj_map * sound_map\n"
        "pos = robot.get_max_pos_3d(fuse_map)\n"
        "robot.move_to(pos)",
    ),
    (
        "reach the sound of a phone ringing near the banana",
        'sound_map = robot.get_major_map(sound="phone ringing")\n'
        'obj_map = robot.get_map(obj="banana")\n'
        "fuse_map = sound_map * obj_map\n"
        "pos = robot.get_max_pos_3d(fuse_map)\n"
        "robot.move_to(pos)",
    ),
    (
        "approach the plate close to the sound of a clock ticking and the sound of typing",
        'obj_map = robot.get_major_map(obj="plate")\n'
        'sound_map = robot.get_map(sound="clock ticking") * robot.get_map(sound="typing")\n'
        "fuse_map = obj_map * sound_map\n"
        "pos = robot.get_max_pos_3d(fuse_map)\n"
        "robot.move_to(pos)",
    ),
    (
        "move halfway between the sound of a bird singing and the image ./views/shelf.png",
        'img = robot.load_image("./views/shelf.png")\n'
        'sound_map = robot.get_major_map(sound="bird singing")\n'
        "img_map = robot.get_major_map(img=img)\n"
        "robot.move_in_between(sound_map, img_map)",
    ),
    (
        "go in between the spoon and the fork near the right side of the table",
        'obj_map = robot.get_major_map(obj="fork")\n'
        'area_map = robot.get_map(area="right side of the table")\n'
        "fuse_map = obj_map * area_map\n"
        'robot.move_in_between("spoon", fuse_map)',
    ),
    (
        "move to the picture /data/goal_3.jpg",
        'img = robot.load_image("/data/goal_3.jpg")\n'
        "img_map = robot.get_major_map(img=img)\n"
        "pos = robot.get_max_pos_3d(img_map)\n"
        "robot.move_to(pos)",
    ),
    (
        "go to the center of the table",
        'area_map = robot.get_major_map(area="center of the table")\n'
        "pos = robot.get_max_pos_3d(area_map)\n"
        "robot.move_to(pos)",
    ),
    (
        "move a little to the right of the orange block, then behind the box",
        'robot.move_to_right("orange block")\nrobot.move_behind("box")',
    ),
    (
        "slide 4 cm to the left and then 10 cm away from me",
        "robot.move_west(0.04)\nrobot.move_north(0.1)",
    ),
    (
        "go back and forth between the toy car and the sound of a bell 3 times",
        'pos1 = robot.above("toy car")\n'
        'pos2 = robot.get_max_pos_3d(robot.get_major_map(sound="bell"))\n'
        "for _ in range(3):\n"
        "    robot.move_to(pos1)\n"
        "    robot.move_to(pos2)",
    ),
)


#: The mobile base's examples (its own motions, and the shared API in a room).
MOBILE_EXAMPLES: tuple[tuple[str, str], ...] = (
    ("go to the green bowl", 'robot.move_to_object("green bowl")'),
    (
        "drive to the cup near the sound of a kettle whistling",
        'obj_map = robot.get_major_map(obj="cup")\n'
        'sound_map = robot.get_map(sound="kettle whistling")\n'
        "robot.move_to(robot.get_max_pos_3d(obj_map * sound_map))",
    ),
    ("move 2 meters forward, then turn left", "robot.move_forward(2)\nrobot.turn(90)"),
    ("turn around and face the armchair", 'robot.turn(180)\nrobot.face("armchair")'),
    (
        "go in between the lamp and the sound of a phone ringing",
        'sound_map = robot.get_major_map(sound="phone ringing")\n'
        'robot.move_in_between("lamp", sound_map)',
    ),
    ("back up half a meter", "robot.move_forward(-0.5)"),
)


#: The arm's prompt (:data:`tabletop.embodiments.ARM`).
ARM_PROMPT = PromptParts(_PREAMBLE, _CONVENTIONS, EXAMPLES)
#: A mobile base's prompt (:data:`tabletop.embodiments.MOBILE`).
MOBILE_PROMPT = PromptParts(_MOBILE_PREAMBLE, _MOBILE_CONVENTIONS, MOBILE_EXAMPLES)

SYSTEM_PROMPT = system_prompt("arm")
"""The arm's system message (:func:`system_prompt`)."""


def _examples(robot: str):
    return _parts(robot).examples


def prompt_text(instruction: str, robot: str = "arm") -> str:
    """The whole prompt as one text (for completion endpoints and for reading)."""
    shots = "\n\n".join(f"# {q}\n{code}" for q, code in _examples(robot))
    return f"{system_prompt(robot)}\n{shots}\n\n# {instruction.strip()}\n"


def prompt_messages(instruction: str, robot: str = "arm") -> list[dict]:
    """Chat messages: the API description, the examples as user/assistant turns, the query
    (for ``robot``, an :mod:`~tabletop.embodiments` name)."""
    messages = [{"role": "system", "content": system_prompt(robot)}]
    for q, code in _examples(robot):
        messages.append({"role": "user", "content": f"# {q}"})
        messages.append({"role": "assistant", "content": code})
    messages.append({"role": "user", "content": f"# {instruction.strip()}"})
    return messages
