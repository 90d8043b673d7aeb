"""Instruction -> code -> sandboxed run: the tracing robot, a real simulated arm, and the
`tabletop parse` / `tabletop run` commands."""

import numpy as np
import pytest

from tabletop.cli import main
from tabletop.errors import ConfigError
from tabletop.language import CodeRejected, ParseError, TracingRobot, run_instruction
from tabletop.language.suite import PointRobot, load_suite, reference_map


@pytest.fixture(scope="module")
def suite():
    return load_suite()


@pytest.fixture(scope="module")
def ref_map(suite):
    return reference_map(suite)


@pytest.fixture(scope="module")
def arm(ref_map):
    from tabletop.robot import SimArm

    a = SimArm(ref_map, "default")
    yield a
    a.close()


def test_dry_run_records_targets_and_moves_nothing(ref_map):
    robot = PointRobot(ref_map, (0.3, 0.0, 0.3))
    seen = []
    run = run_instruction(
        "move to the left of the red mug, then move 5 cm north twice",
        robot,
        dry_run=True,
        on_motion=seen.append,
    )
    assert [m.method for m in run.motions] == ["move_to_left", "move_north", "move_north"]
    left = robot.left_of("red mug")
    np.testing.assert_allclose(run.targets[0], left)
    np.testing.assert_allclose(run.targets[2], np.add(left, [0.1, 0.0, 0.0]))
    np.testing.assert_allclose(robot.current_position(), [0.3, 0.0, 0.3])  # never moved
    assert all(m.result is None for m in run.motions) and len(seen) == 3
    assert run.code.startswith("# move to the left of the red mug\n")


def test_a_robot_that_returns_no_result_is_reported_once_per_motion(ref_map):
    seen = []
    run = run_instruction(
        "go to the red mug, then move 5 cm north", PointRobot(ref_map), on_motion=seen.append
    )
    assert len(run.motions) == 2 and [m.method for m in seen] == [m.method for m in run.motions]


def test_tracing_robot_targets_equal_the_robot_apis_own(ref_map):
    robot = PointRobot(ref_map)
    t = TracingRobot(robot, execute=True)
    t.move_in_between("red mug", "tray")
    t.move_behind("tray")
    t.move_east(0.02)
    np.testing.assert_allclose(t.targets[0], robot.between("red mug", "tray"))
    np.testing.assert_allclose(t.targets[1], robot.behind("tray"))
    np.testing.assert_allclose(t.targets[2], np.add(robot.behind("tray"), [0, -0.02, 0]))
    np.testing.assert_allclose(robot.current_position(), t.targets[2])  # executed
    with pytest.raises(Exception, match="finite 3-vector"):
        t.move_to((0.1, 0.2))
    with pytest.raises(Exception, match="a number"):
        t.move_north("far")


def test_every_traced_motion_goes_to_its_declared_target(ref_map):
    from tabletop.robot.primitives import PRIMITIVES

    robot = PointRobot(ref_map, (0.3, 0.0, 0.3))
    args = {"name": "red mug", "a": "red mug", "b": "tray", "distance_m": 0.04}
    for p in PRIMITIVES:
        if not p.moves or p.target is None or not p.available_to("arm"):
            continue
        t = TracingRobot(robot, execute=False, start=(0.3, 0.0, 0.3))
        values = [args[n] for n in p.params]
        getattr(t, p.name)(*values)
        if p.direction is not None:
            expected = np.add((0.3, 0.0, 0.3), [0.04 * p.direction[0], 0.04 * p.direction[1], 0])
        else:
            expected = getattr(robot, p.target)(*values)
        assert [m.method for m in t.motions] == [p.name]
        np.testing.assert_allclose(t.targets[0], expected, err_msg=p.name)
    np.testing.assert_allclose(robot.current_position(), [0.3, 0.0, 0.3])  # a dry run
    with pytest.raises(TypeError, match="distance_m"):
        TracingRobot(robot).move_north()
    # a mobile base's own motions, asked of an arm, are refused by name before anything moves
    for call, arg in (("move_forward", 1.0), ("turn", 90), ("face", "red mug"), ("ahead", 1)):
        t = TracingRobot(robot, execute=False)
        with pytest.raises(ConfigError, match=f"{call} is a primitive of the mobile robot"):
            getattr(t, call)(arg)
        assert t.motions == []


def test_the_arm_does_not_move_for_refused_code_or_instructions(arm):
    q0 = arm.driver.read_state().q.copy()
    n0 = len(arm.history)
    with pytest.raises(CodeRejected, match="import"):
        run_instruction("x", arm, code="robot.move_north(0.05)\nimport os\n")
    with pytest.raises(CodeRejected, match="while"):
        run_instruction("x", arm, code="while True:\n    robot.move_north(0.01)\n")
    with pytest.raises(ParseError, match="negated goal"):
        run_instruction("don't go to the mug", arm)
    assert len(arm.history) == n0
    np.testing.assert_array_equal(arm.driver.read_state().q, q0)


def test_the_arm_reaches_an_instructions_targets(arm):
    seen = []
    n0 = len(arm.history)
    run = run_instruction("go to the red mug, then move 5 cm north", arm, on_motion=seen.append)
    assert [m.method for m in run.motions] == ["move_to_object", "move_north"]
    assert [m.result for m in run.motions] == arm.history[n0:]
    for m in run.motions:
        assert m.result.reached, m.result.reason
        assert np.linalg.norm(m.result.final_tcp - m.target) <= 0.01
    np.testing.assert_allclose(run.targets[0], arm.above("red mug"))
    # the compass move starts where the arm really is
    np.testing.assert_allclose(
        run.targets[1], np.add(run.motions[0].result.final_tcp, [0.05, 0.0, 0.0]), atol=1e-6
    )
    assert [m.result is None for m in seen] == [True, False, True, False]  # target, result


def test_cli_parse_prints_the_code_the_sandbox_gets(capsys):
    assert main(["parse", "go to the mug near the sound of a dog barking"]) == 0
    out = capsys.readouterr().out
    assert out == (
        "# go to the mug near the sound of a dog barking\n"
        'obj_map = robot.get_major_map(obj="mug")\n'
        'sound_map = robot.get_map(sound="dog barking")\n'
        "fuse_map = obj_map * sound_map\n"
        "pos = robot.get_max_pos_3d(fuse_map)\n"
        "robot.move_to(pos)\n"
    )
    assert main(["parse", "whistle a tune for me"]) == 2
    err = capsys.readouterr().err
    assert "did not understand 'whistle a tune for me'" in err and "asks something else" in err
    assert main(["parse", "go to the mug", "--backend", "llm"]) == 2
    assert "TABLETOP_LLM_BASE_URL" in capsys.readouterr().err


def test_cli_run_dry_run_shows_code_and_targets(capsys, ref_map):
    rc = main(["run", "reference", "go to the image goal_teddy.png then 3 cm south", "--dry-run"])
    out = capsys.readouterr().out
    assert rc == 0
    assert "  3 | img_map = robot.get_major_map(img=img)" in out
    assert "dry run: nothing moves" in out
    lines = [ln for ln in out.splitlines() if "target (" in ln]
    assert len(lines) == 2 and "move_south" in lines[1]
    assert "2 target(s)" in out


def test_words_read_as_an_image_that_is_no_file_are_named_for_both(ref_map, tmp_path):
    # "image 'nothing.png' is not found": the request's words were blamed on an image path
    robot = PointRobot(ref_map, (0.3, 0.0, 0.3))
    with pytest.raises(ConfigError, match="read neither as a thing nor as an existing image") as e:
        run_instruction("go to ./nothing.png", robot, dry_run=True, image_dir=tmp_path)
    assert "'./nothing.png'" in str(e.value) and "is not found" in str(e.value)
    assert str(tmp_path) in str(e.value)
