"""Code generation: the robot code written from a plan, every call a declared primitive."""

import ast

import pytest

from tabletop.language import (
    ParseError,
    check_code,
    instruction_to_code,
    parse_instruction,
    plan_to_code,
)
from tabletop.language.suite import load_suite
from tabletop.reader.plan import Between, Goal, GoTo, Part, Side, Step
from tabletop.robot.primitives import PRIMITIVES


def robot_calls(code):
    return [
        n.func.attr
        for n in ast.walk(ast.parse(code))
        if isinstance(n, ast.Call)
        and isinstance(n.func, ast.Attribute)
        and isinstance(n.func.value, ast.Name)
        and n.func.value.id == "robot"
    ]


def test_every_pair_of_modalities_fuses_sharp_primary_with_broad_constraint():
    phrases = {
        "obj": "the duck",
        "sound": "the sound of a cat meowing",
        "img": "the image ./a.png",
        "area": "the tray area",
    }
    # (a thing near a thing of the same words is refused: the constraint names another one)
    others = {
        "obj": "the mug",
        "sound": "the sound of a dog barking",
        "img": "the image ./b.png",
        "area": "the middle of the table",
    }
    for k1, p1 in phrases.items():
        for k2, p2 in others.items():
            code = instruction_to_code(f"go to {p1} near {p2}")
            tree = ast.parse(code)
            calls = [
                n.func.attr
                for n in ast.walk(tree)
                if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)
            ]
            assert calls.count("get_major_map") == 1 and calls.count("get_map") == 1, code
            major = next(
                n
                for n in ast.walk(tree)
                if isinstance(n, ast.Call) and n.func.attr == "get_major_map"
            )
            broad = next(
                n for n in ast.walk(tree) if isinstance(n, ast.Call) and n.func.attr == "get_map"
            )
            assert major.keywords[0].arg == k1 and broad.keywords[0].arg == k2
            assert " * " in code and code.rstrip().endswith("robot.move_to(pos)")
            check_code(code)


def test_two_constraints_multiply():
    code = instruction_to_code(
        "go to the duck near the sound of a cat meowing and the sound of a dog barking"
    )
    assert "fuse_map = obj_map * sound_map * sound_map_2" in code


def test_back_and_forth_loops_over_two_fixed_points():
    code = instruction_to_code("move back and forth between the sofa and the table 3 times")
    assert code.endswith("for _ in range(3):\n    robot.move_to(pos1)\n    robot.move_to(pos2)\n")
    assert 'pos1 = robot.above("sofa")' in code


def test_code_is_commented_per_step_and_passes_the_sandbox():
    code = instruction_to_code("go to the image ./Goal.PNG, then move 4 cm east")
    assert code.splitlines()[0] == "# go to the image ./Goal.PNG"
    assert 'robot.load_image("./Goal.PNG")' in code  # the path keeps its case
    assert "# move 4 cm east" in code
    check_code(code)


def test_between_moves_between_two_landmarks_objects_by_name_others_as_heatmaps():
    code = instruction_to_code("go halfway between the red mug and the duck")
    assert code.splitlines()[1:] == ['robot.move_in_between("red mug", "duck")']
    code = instruction_to_code("go between the tray and where you heard the dog barking")
    assert code == (
        "# go between the tray and where you heard the dog barking\n"
        'sound_map = robot.get_major_map(sound="dog barking")\n'
        'robot.move_in_between("tray", sound_map)\n'
    )
    code = instruction_to_code(
        "move in between the image ./006899.png and the backpack near the sound of glass"
    )
    assert code.splitlines()[1:] == [
        'img = robot.load_image("./006899.png")',
        "img_map = robot.get_major_map(img=img)",
        'obj_map = robot.get_major_map(obj="backpack")',
        'sound_map = robot.get_map(sound="glass")',
        "fuse_map = obj_map * sound_map",
        "robot.move_in_between(img_map, fuse_map)",
    ]
    assert "get_max_pos_3d" not in code and "/ 2" not in code  # no averaging by hand
    check_code(code)


def test_a_relation_to_a_narrowed_object_passes_its_fused_heatmap():
    code = instruction_to_code("move to the left of the mug near the sound of a dog barking")
    assert code.splitlines()[1:] == [
        'obj_map = robot.get_major_map(obj="mug")',
        'sound_map = robot.get_map(sound="dog barking")',
        "fuse_map = obj_map * sound_map",
        "robot.move_to_left(fuse_map)",
    ]
    check_code(code)
    assert instruction_to_code("go above the mug").splitlines()[1:] == [
        'robot.move_to_object("mug")'
    ]


def test_repetition_loops_over_the_motion_only():
    code = instruction_to_code("move 5 cm north 3 times")
    assert "for _ in range(3):\n    robot.move_north(0.05)" in code
    code = instruction_to_code("go between the duck and the sound of a cat meowing twice")
    assert code.splitlines()[1:] == [
        'sound_map = robot.get_major_map(sound="cat meowing")',
        "for _ in range(2):",
        '    robot.move_in_between("duck", sound_map)',
    ]


def test_every_generated_call_is_a_declared_primitive():
    declared = {p.name for p in PRIMITIVES}
    used = set()
    for case in load_suite().cases:
        used |= set(robot_calls(instruction_to_code(case.instruction)))
    assert used <= declared
    assert {"move_in_between", "move_to_left", "move_behind", "move_north", "above"} <= used


def test_a_hand_built_plan_is_written_with_its_strings_quoted():
    text = 'mug") ; import os ; ("'
    plan = (
        Step(GoTo(Goal(Part("obj", "red mug"), (Part("sound", text),))), 1, "go\nthere"),
        Step(Side("left", text), 2, "left"),
        Step(Between(Goal(Part("obj", text)), Goal(Part("area", "tray area"))), 1, "between"),
    )
    code = plan_to_code(plan)
    check_code(code)  # one statement per line, nothing but robot calls
    strings = [n.value for n in ast.walk(ast.parse(code)) if isinstance(n, ast.Constant)]
    assert strings.count(text) == 3
    assert code.startswith("# go there\n")


def test_unknown_goal_kinds_are_refused_in_the_plan():
    with pytest.raises(Exception, match="unknown goal kind 'smell'; valid"):
        Part("smell", "coffee")


def test_instruction_to_code_refuses_what_the_parser_refuses():
    with pytest.raises(ParseError, match="motion verb"):
        instruction_to_code("juggle", reader="rules+spelling")
    with pytest.raises(ParseError, match="asks something else"):  # the default reader
        instruction_to_code("dance around the table")
    assert plan_to_code(parse_instruction("go to the duck")) == instruction_to_code(
        "go to the duck"
    )
