"""Robots declared once (:mod:`tabletop.embodiments`): the shipped robots' specs, and a third,
toy robot built from a spec alone (its robot class and prompt live in this test file; nothing
else changes) that task files, the reader, the prompt, the robot API's limits, the CLI and a
whole evaluation accept."""

from dataclasses import dataclass

import numpy as np
import pytest

from tabletop.embodiments import EMBODIMENTS, Embodiment, embodiment, register, unregister
from tabletop.errors import ConfigError
from tabletop.language.prompts import PromptParts
from tabletop.robot.api import RobotAPI
from tabletop.robot.primitives import primitives_of

# ------------------------------------------------------------------------- the toy robot
GANTRY_PROMPT = PromptParts(
    "You write Python for a gantry that carries a pointer over a table.\n",
    "The gantry jumps to any point over the table.\n",
    (("go to the mug", 'robot.move_to_object("mug")'),),
)


@dataclass
class Jump:
    """A toy move's result: it always arrives."""

    reached: bool
    reason: str
    final_position: np.ndarray


class PointGantry(RobotAPI):
    """A toy robot: a pointer on a gantry over the table that jumps to its target."""

    robot_kind = "gantry"
    home = np.array([0.45, 0.0, 0.45])

    def __init__(self, avlmap, spec=None) -> None:
        super().__init__(avlmap)
        self.reset()

    def reset(self) -> None:
        self.position = self.home.copy()
        self.history: list[Jump] = []
        self.contacts: list[int] = []

    def move_to(self, pos):
        self.position = np.asarray(pos, np.float64).copy()
        self.history.append(Jump(True, "reached", self.position.copy()))
        self.contacts.append(0)
        return self.history[-1]

    def current_position(self) -> np.ndarray:
        return self.position.copy()


GANTRY = Embodiment(
    name="gantry",
    summary="a toy pointer on a gantry over a table",
    robot_class=f"{__name__}:PointGantry",
    success_radius_m=0.15,
    max_move_m=0.5,
    workspace="scene",
    prompt=f"{__name__}:GANTRY_PROMPT",
)


@pytest.fixture
def gantry():
    register(GANTRY)
    try:
        yield GANTRY
    finally:
        unregister("gantry")


# ------------------------------------------------------------------------- the shipped robots
def test_the_shipped_robots_declare_what_differs_between_them():
    arm, base = embodiment("arm"), embodiment("mobile")
    assert (arm.success_radius_m, base.success_radius_m) == (0.10, 1.0)
    assert (arm.workspace, base.workspace) == ("scene", "room")
    assert not arm.drives and base.drives and base.obstacles == ("ground", "flyer")
    assert {p.name for p in primitives_of("mobile")} - {p.name for p in primitives_of("arm")} == {
        "ahead",
        "move_forward",
        "turn",
        "face",
    }
    assert arm.load("robot_class").robot_kind == "arm"
    assert base.load("robot_class").robot_kind == "mobile"
    assert "franky-sim" in arm.drivers and base.drivers == ("sim",)
    for e in EMBODIMENTS.values():  # every lazy part of a shipped robot imports
        for part in ("robot_class", "prompt", "scan_config", "evaluate", "suites", "demo"):
            assert e.load(part) is not None, (e.name, part)


def test_bad_specs_and_names_are_refused_naming_the_valid_choices():
    with pytest.raises(ConfigError, match=r"unknown robot 'boat'; valid: \['arm', 'mobile'"):
        embodiment("boat")
    with pytest.raises(ConfigError, match="workspace must be one of"):
        Embodiment("x", "", "m:C", 0.1, 1.0, "garden")
    with pytest.raises(ConfigError, match="success_radius_m must be a number > 0"):
        Embodiment("x", "", "m:C", 0.0, 1.0, "scene")
    with pytest.raises(ConfigError, match="robot_class must be 'module:attribute'"):
        Embodiment("x", "", "no_colon", 0.1, 1.0, "scene")
    with pytest.raises(ConfigError, match="is registered already"):
        register(embodiment("arm"))
    with pytest.raises(ConfigError, match="cannot be loaded"):
        register(Embodiment("x", "", "tabletop.robot.api:NoSuchRobot", 0.1, 1.0, "scene"))
    assert "x" not in EMBODIMENTS  # a spec that fails to load is not half-registered
    with pytest.raises(ConfigError, match="cannot be removed"):
        unregister("arm")


# ------------------------------------------------------------------------- a third robot
def test_a_toy_robot_from_its_spec_alone_reaches_the_reader_prompt_api_and_task_files(
    gantry, capsys
):
    from tabletop.eval.tasks import parse_tasks
    from tabletop.language.prompts import prompt_messages, system_prompt
    from tabletop.reader.errors import ParseError
    from tabletop.reader.rules import parse_instruction
    from tabletop.robot.api import compass_limit_m

    # the prompt: its own words, the shared API and none of a base's own motions
    text = system_prompt("gantry")
    assert text.startswith("You write Python for a gantry") and "robot.move_to(pos)" in text
    assert "move_forward" not in text and "turn(" not in text
    assert prompt_messages("go to the duck", "gantry")[2]["content"] == GANTRY_PROMPT.examples[0][1]
    # the reader holds it to its own longest move, and reads no drive or turn of a base
    assert compass_limit_m("gantry") == 0.5
    assert parse_instruction("move north 40 cm", "gantry")
    with pytest.raises(ParseError, match="at most 0.5 m"):
        parse_instruction("move north 80 cm", "gantry")
    assert parse_instruction("move north 80 cm", "arm")  # the arm's limit is a metre
    with pytest.raises(ParseError):
        parse_instruction("turn left 90 degrees", "gantry")
    # a task file for it: a [scene] (its workspace), its success radius by default
    doc = {
        "format": "tabletop-tasks",
        "version": 1,
        "robot": {"kind": "gantry"},
        "scene": {"name": "default"},
        "goals": [
            {
                "id": "g",
                "type": "object",
                "text": "the mug",
                "query": {"obj": "mug"},
                "truth": {"object": "red_mug"},
            }
        ],
    }
    tf = parse_tasks(doc)
    assert tf.robot.kind == "gantry" and tf.robot.success_radius == 0.15
    assert tf.robot.embodiment is None and tf.robot.body is GANTRY
    with pytest.raises(Exception, match=r"needs a \[scene\] section"):
        parse_tasks({**{k: v for k, v in doc.items() if k != "scene"}, "room": {"name": "x"}})
    # the CLI offers it: the code of an instruction for it
    from tabletop.cli import main

    assert main(["parse", "--robot", "gantry", "go to the mug"]) == 0
    assert 'move_to_object("mug")' in capsys.readouterr().out


def test_a_toy_robot_runs_a_whole_evaluation(gantry, tmp_path):
    from tabletop.eval import run_eval
    from tabletop.eval.runner import scan_recording
    from tabletop.eval.suites import generate_suite, to_toml
    from tabletop.sim.ground_truth import GroundTruth

    scene = {"name": "default"}
    scan = {"seed": 1, "speed": 0.6, "episodes": 2, "episode_s": 2.0, "repeat_sounds": 0}
    rec, _ = scan_recording(scene, scan, tmp_path / "cache")
    counts = dict(
        object=2, sound=0, image=0, area=0, amb_sound=0, amb_image=0, amb_object=0, amb_area=0,
        spatial=1, mm_spatial=0, instruction=1, sequences=0,
    )  # fmt: skip
    doc = generate_suite("toy", scene, scan, GroundTruth.of(rec), counts, seed=3,
                         map_section={"frame_step": 4})  # fmt: skip
    doc["robot"] = {"kind": "gantry"}
    path = tmp_path / "toy.toml"
    path.write_text(to_toml(doc))
    res = run_eval(path, encoders="oracle", progress=False, cache_dir=tmp_path / "cache")
    d = res.to_json()
    assert d["robot"] == "gantry" and d["success_radius_m"] == 0.15
    goals = [g for t in d["rows"][0]["tasks"] for g in t["goals"]]
    assert len(goals) == 4
    # the gantry jumps to every target the oracle map gives: each goal within its radius
    assert all(g["success"] for g in goals), [(g["goal_id"], g["reason"]) for g in goals]
    with pytest.raises(ConfigError, match="does not move the gantry robot"):
        run_eval(path, encoders="oracle", progress=False, driver="franky-sim")
