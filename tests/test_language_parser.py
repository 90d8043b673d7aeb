"""The offline instruction parser's grammar: the plans it makes and what it refuses (the code
written from a plan: tests/test_language_codegen.py)."""

import pytest

from tabletop.language import ParseError, parse_instruction
from tabletop.language.suite import load_suite
from tabletop.reader.plan import (
    Above,
    BackAndForth,
    Between,
    Compass,
    Goal,
    GoTo,
    Part,
    Side,
)


def only(instruction):
    steps = parse_instruction(instruction)
    assert len(steps) == 1
    return steps[0]


@pytest.mark.parametrize(
    "text",
    [
        "go to the red mug",
        "move to the red mug",
        "reach the red mug",
        "approach the red mug",
        "Please head to the red mug.",
        "navigate to the red mug",
        "move the gripper to the red mug",
        # requests as people word them
        "could you move to the red mug",
        "Can you go to the red mug, please?",
        "I want you to go to the red mug",
        "okay, now go over to the red mug",
        "move your hand to the red mug",
        "steer the gripper to the red mug",
        # the robot's own part with words before its noun is still the robot's
        "nudge your little claw over to the red mug",
        "bring your long metal arm across to the red mug",
        "go and touch the red mug",
        "make your way to the red mug",
        "move closer to the red mug",
        "point at the red mug",
    ],
)
def test_motion_verbs_give_the_same_object_goal(text):
    step = only(text)
    assert step.action == GoTo(Goal(Part("obj", "red mug")))
    assert step.times == 1


@pytest.mark.parametrize(
    "text, action",
    [
        ("move to the spot between the mug and the duck", Between),
        ("go to a point between the tray and the ball", Between),
        ("move to the space behind the mug", Side),
        ("go to the place just left of the mug", Side),
        ("go to the mug's left", Side),
        ("move to the mug's back side", Side),
        ("hover over the mug", Above),
        ("position the gripper above the mug", Above),
    ],
)
def test_places_named_by_a_relation(text, action):
    step = only(text)
    assert isinstance(step.action, action)
    if action is Side:
        assert step.action.landmark == "mug"
        assert step.action.side in ("behind", "left")


@pytest.mark.parametrize(
    "text, goal",
    [
        ("go to where the dog barked", Goal(Part("sound", "dog barked"))),
        ("go to the spot where the alarm went off", Goal(Part("sound", "alarm went off"))),
        ("go to where the mug is", Goal(Part("obj", "mug"))),
        (
            "go to the mug near where the dog barked",
            Goal(Part("obj", "mug"), (Part("sound", "dog barked"),)),
        ),
    ],
)
def test_where_something_was_heard_is_a_sound(text, goal):
    assert only(text).action == GoTo(goal)


def test_a_polite_wrapper_keeps_steps_and_repeats():
    steps = parse_instruction("could you hover over the duck twice, then go to the mug please")
    assert [type(s.action) for s in steps] == [Above, GoTo]
    assert steps[0].times == 2 and steps[1].action == GoTo(Goal(Part("obj", "mug")))


@pytest.mark.parametrize(
    "text, kind, desc",
    [
        ("go to the sound of a dog barking", "sound", "dog barking"),
        ("go to the noise of the piano playing", "sound", "piano playing"),
        ("go to the alarm clock sound", "sound", "alarm clock"),
        ("go to where you heard the cat meowing", "sound", "cat meowing"),
        ("go to the place where you heard the cat meowing", "sound", "cat meowing"),
        ("go to where the cat meowing was heard", "sound", "cat meowing"),
        ("go to the left side of the table", "area", "left side of the table"),
        ("go to the far side of the table", "area", "front of the table"),
        ("go to the middle of the table", "area", "center of the table"),
        ("go to the tray area", "area", "tray area"),
        ("go to the image ./Goals/View_1.PNG", "img", "./Goals/View_1.PNG"),
        ("go to the picture /tmp/a b/../x.jpg", None, None),
        ("go to the place shown in the image goal.png", "img", "goal.png"),
        ("go to the view in 'shots/a.jpeg'", "img", "shots/a.jpeg"),
    ],
)
def test_modalities_are_recognised(text, kind, desc):
    if kind is None:  # a path with a space is two words: the parser refuses, never guesses
        with pytest.raises(ParseError):
            parse_instruction(text)
        return
    assert only(text).action == GoTo(Goal(Part(kind, desc)))


@pytest.mark.parametrize(
    "connector", ["near", "next to", "close to", "beside", "that is near", "by", "nearest to"]
)
def test_near_phrasings(connector):
    step = only(f"go to the mug {connector} the sound of a dog barking")
    assert step.action == GoTo(Goal(Part("obj", "mug"), (Part("sound", "dog barking"),)))


@pytest.mark.parametrize(
    "connector",
    [
        "right by",
        "just next to",
        "close by",
        "hard by",
        "nearby",
        "alongside",
        "adjacent to",
        "not far from",
        "in the vicinity of",
        "neighbouring",
        "sitting near",
        "that sits beside",
        "which is lying next to",
        "over by",
        "in the same spot as",
    ],
)
def test_near_phrasings_people_use(connector):
    step = only(f"go to the mug {connector} the sound of a dog barking")
    assert step.action == GoTo(Goal(Part("obj", "mug"), (Part("sound", "dog barking"),)))


@pytest.mark.parametrize(
    "sound",
    [
        "the noise like a dog barking",
        "the sound that sounded like a dog barking",
        "a racket of a dog barking",
        "that dog barking noise",
        "the dog barking you heard",
        "the dog you heard barking",
        "the dog barking sound we heard earlier",
        "the sound you heard of a dog barking",
        "where the dog barking came from",
        "the spot the dog barking was coming from",
        "where you could hear a dog barking",
        "where a dog barking could be heard",
    ],
)
def test_a_sound_told_as_people_tell_it(sound):
    step = only(f"go to the mug near {sound}")
    assert step.action == GoTo(Goal(Part("obj", "mug"), (Part("sound", "dog barking"),)))


@pytest.mark.parametrize(
    "text",
    [
        "pop over to the red mug",
        "swing over to the red mug",
        "reach out to the red mug",
        "go on over to the red mug",
        "take me to the red mug",
        "position yourself at the red mug",
        "put your hand on the red mug",
        "tap the red mug",
        "aim for the red mug",
        "make for the red mug",
        "track down the red mug",
        "go find the red mug",
        "get as close as you can to the red mug",
        "let's go to the red mug",
        "I need you over by the red mug",
        "go stand next to the red mug",
        "proceed to the red mug",
    ],
)
def test_more_ways_to_say_go_to(text):
    assert only(text).action == GoTo(Goal(Part("obj", "red mug")))


@pytest.mark.parametrize(
    "text, action",
    [
        ("stop just to the left of the mug", Side("left", "mug")),
        ("go round the back of the mug", Side("behind", "mug")),
        ("move in back of the mug", Side("behind", "mug")),
        # the robot's convention: the front of X is its side away from the robot
        ("go to the far side of the mug", Side("front", "mug")),
        ("go on the other side of the mug", Side("front", "mug")),
        ("go to the near side of the mug", Side("behind", "mug")),
        ("move ahead of the mug", Side("front", "mug")),
        ("go on top of the mug", Above("mug")),
        (
            "go to the gap between the mug and the duck",
            Between(Goal(Part("obj", "mug")), Goal(Part("obj", "duck"))),
        ),
        (
            "go midway between the mug and the duck",
            Between(Goal(Part("obj", "mug")), Goal(Part("obj", "duck"))),
        ),
        (
            "go halfway from the mug to the duck",
            Between(Goal(Part("obj", "mug")), Goal(Part("obj", "duck"))),
        ),
        (
            "go to the point equidistant from the mug and the duck",
            Between(Goal(Part("obj", "mug")), Goal(Part("obj", "duck"))),
        ),
    ],
)
def test_more_ways_to_name_a_relation(text, action):
    assert only(text).action == action


@pytest.mark.parametrize(
    "text, action",
    [
        ("go just left of the mug", Side("left", "mug")),
        ("go around behind the mug", Side("behind", "mug")),
        ("go just past the mug", Side("front", "mug")),
        ("head to the side of the mug facing you", Side("behind", "mug")),
        ("head to the side of the mug facing away from you", Side("front", "mug")),
        ("go next to the mug, on its left", Side("left", "mug")),
        ("move to the mug's left-hand side", Side("left", "mug")),
        ("behind the mug, please", Side("behind", "mug")),
        ("tuck in behind the mug", Side("behind", "mug")),
        ("point just in front of the mug", Side("front", "mug")),
        (
            "aim for the gap separating the mug from the duck",
            Between(Goal(Part("obj", "mug")), Goal(Part("obj", "duck"))),
        ),
        (
            "stop halfway between the mug and the duck",
            Between(Goal(Part("obj", "mug")), Goal(Part("obj", "duck"))),
        ),
        ("go to wherever the dog barking came from", GoTo(Goal(Part("sound", "dog barking")))),
        ("go to the spot you heard the dog barking", GoTo(Goal(Part("sound", "dog barking")))),
        ("go to the area the barking seemed to come from", GoTo(Goal(Part("sound", "barking")))),
        ("go to the corner where the barking could be heard", GoTo(Goal(Part("sound", "barking")))),
        ("go to the location of the dog barking", GoTo(Goal(Part("sound", "dog barking")))),
        ("go to where the dog barking was playing", GoTo(Goal(Part("sound", "dog barking")))),
        ("go to where the mug was", GoTo(Goal(Part("obj", "mug")))),
        ("go to the place the dog barking was loudest", GoTo(Goal(Part("sound", "dog barking")))),
        (
            "go to the mug a stone's throw from the barking",
            GoTo(Goal(Part("obj", "mug"), (Part("sound", "barking"),))),
        ),
        (
            "go to the mug sat right up against the barking",
            GoTo(Goal(Part("obj", "mug"), (Part("sound", "barking"),))),
        ),
        ("try going to the mug", GoTo(Goal(Part("obj", "mug")))),
        ("next, go to the mug", GoTo(Goal(Part("obj", "mug")))),
        ("put your finger on the mug", GoTo(Goal(Part("obj", "mug")))),
    ],
)
def test_still_more_wording_people_use(text, action):
    assert only(text).action == action


@pytest.mark.parametrize("text", ["go get the red mug", "fetch the red mug"])
def test_fetching_is_grasping_and_refused(text):
    # the arm moves to places; "get" and "fetch" ask it to bring the thing, which it cannot
    with pytest.raises(ParseError):
        parse_instruction(text)


def test_where_after_an_object_joins_the_place_where_something_happened():
    assert only("go to the mug where the phone rang").action == GoTo(
        Goal(Part("obj", "mug"), (Part("sound", "phone rang"),))
    )
    assert only("go to the spot where the phone rang").action == GoTo(
        Goal(Part("sound", "phone rang"))
    )
    # "where X is" is still the object X
    assert only("go to the duck where the mug is").action == GoTo(
        Goal(Part("obj", "duck"), (Part("obj", "mug"),))
    )
    # a negation is no near word: refused, never read as "near"
    with pytest.raises(ParseError):
        parse_instruction("go to the mug not near the sound of a dog barking")


def test_where_you_heard_makes_the_constraint_a_sound():
    step = only("reach the mug where you heard the alarm clock")
    assert step.action.goal.near == (Part("sound", "alarm clock"),)


def test_a_sound_description_may_hold_commas_but_not_structure():
    # The sound bank's own captions have commas ("splashing, dripping water").
    step = only("move to the sound of splashing, dripping water")
    assert step.action == GoTo(Goal(Part("sound", "splashing, dripping water")))
    step = only("go to the duck near the sound of splashing, dripping water")
    assert step.action.goal.near == (Part("sound", "splashing, dripping water"),)
    with pytest.raises(ParseError, match="'left,'"):
        parse_instruction("go to the sound of water, left, of the mug")


def test_between_splits_at_the_first_valid_and():
    step = only("move in between the image ./006899.png and the backpack near the sound of glass")
    assert step.action == Between(
        Goal(Part("img", "./006899.png")),
        Goal(Part("obj", "backpack"), (Part("sound", "glass"),)),
    )
    assert only("go halfway between the red mug and the duck").action == Between(
        Goal(Part("obj", "red mug")), Goal(Part("obj", "duck"))
    )


@pytest.mark.parametrize(
    "text, side",
    [
        ("move to the left of the red mug", "left"),
        ("go to the left-hand side of the red mug", "left"),
        ("move on the right side of the red mug", "right"),
        ("go in front of the red mug", "front"),
        ("approach the front side of the red mug", "front"),
        ("go behind the red mug", "behind"),
        ("go to the back of the red mug", "behind"),
        ("move to the rear of the red mug", "behind"),
    ],
)
def test_sides_of_a_landmark(text, side):
    assert only(text).action == Side(side, "red mug")


def test_the_table_sides_are_areas_not_landmarks():
    assert only("go to the back of the table").action == GoTo(
        Goal(Part("area", "back of the table"))
    )
    assert only("go to the left side of the table near the duck").action == GoTo(
        Goal(Part("area", "left side of the table"), (Part("obj", "duck"),))
    )


@pytest.mark.parametrize(
    "text, direction, dist",
    [
        ("move 10 cm north", "north", 0.1),
        ("move north by 10 cm", "north", 0.1),
        ("go 0.1 m forward", "north", 0.1),
        ("move left 5 centimetres", "west", 0.05),
        ("move 50 mm to the right", "east", 0.05),
        ("go back 3 cm", "south", 0.03),
        ("move ten centimeters to the south", "south", 0.1),
    ],
)
def test_compass_moves(text, direction, dist):
    a = only(text).action
    assert a == Compass(direction, pytest.approx(dist))


def test_sequences_and_repetition():
    steps = parse_instruction(
        "first move to the left of the tray, then move between the ball and the duck, "
        "and then go back and forth between the red mug and the blue mug twice; "
        "after that move 5 cm north 3 times. Finally go above the tray"
    )
    assert [type(s.action) for s in steps] == [Side, Between, BackAndForth, Compass, Above]
    assert [s.times for s in steps] == [1, 1, 2, 3, 1]
    assert only("move 5 cm north 3 times").times == 3
    # later steps may leave the verb out
    steps = parse_instruction("go to the red mug, then the duck, then twice to the tray")
    assert [s.action for s in steps] == [
        GoTo(Goal(Part("obj", "red mug"))),
        GoTo(Goal(Part("obj", "duck"))),
        GoTo(Goal(Part("obj", "tray"))),
    ]
    assert steps[2].times == 2


def test_quotes_in_descriptions_cannot_break_out_of_the_string():
    with pytest.raises(ParseError):
        parse_instruction('go to the mug") ; import os ; ("')


@pytest.mark.parametrize(
    "text, fragment, words",
    [
        ("", "", "empty"),
        ("dance", "dance", "motion verb"),
        ("go to the mug and the duck", "the mug and the duck", "'and'"),
        ("go north", "north", "distance"),
        ("move 2 m west", "2 m west", "at most 1.0 m"),
        ("go to the mug 21 times", "21 times", "1 to 20"),
        ("go to the left of the sound of rain", "the sound of rain", "an object"),
        ("go to the picture", "the picture", "file path"),
        ("go to the mug slowly", "the mug slowly", "'slowly'"),
        ("go to the image a.png b.png", "the image a.png b.png", "one path"),
        ("go to the mug, then, then the duck", None, "empty step"),
        ("go between the mug", "the mug", "two goals"),
        ("do not go to the mug", "do not go to the mug", "motion verb"),
    ],
)
def test_refusals_name_what_was_not_understood(text, fragment, words):
    with pytest.raises(ParseError) as e:
        parse_instruction(text)
    if fragment is not None:
        assert e.value.fragment == fragment
    assert words in str(e.value)
    assert repr(text) in str(e.value) or not text


def test_the_suites_unparseable_instructions_are_refused():
    suite = load_suite()
    assert len(suite.unparseable) >= 10
    for bad in suite.unparseable:
        with pytest.raises(ParseError) as e:
            parse_instruction(bad.instruction)
        assert e.value.fragment == bad.fragment, bad.instruction


@pytest.mark.parametrize(
    "text, code",
    [
        ("move forward 2 meters", ["robot.move_forward(2.0)"]),
        ("drive 3 m forward", ["robot.move_forward(3.0)"]),
        ("back up 50 cm", ["robot.move_forward(-0.5)"]),
        ("go backwards 1 m", ["robot.move_forward(-1.0)"]),
        ("turn left", ["robot.turn(90.0)"]),
        ("turn 45 degrees to the right", ["robot.turn(-45.0)"]),
        ("rotate 30 degrees clockwise", ["robot.turn(-30.0)"]),
        ("turn around", ["robot.turn(180.0)"]),
        ("face the teddy bear", ['robot.face("teddy bear")']),
        ("turn to face the blue mug", ['robot.face("blue mug")']),
        ("move 2 m north", ["robot.move_north(2.0)"]),
        (
            "go to the red mug, then turn right, then move forward 1 m",
            ['robot.move_to_object("red mug")', "robot.turn(-90.0)", "robot.move_forward(1.0)"],
        ),
    ],
)
def test_a_mobile_base_turns_faces_and_drives(text, code):
    from tabletop.language.codegen import instruction_to_code

    lines = [x for x in instruction_to_code(text, "mobile").splitlines() if not x.startswith("#")]
    assert lines == code


@pytest.mark.parametrize(
    "text, robot, why",
    [
        ("turn left", "arm", "a mobile base's motions"),
        ("face the duck", "arm", "a mobile base's motions"),
        ("move 1 m left", "mobile", "does not move sideways"),
        ("turn", "mobile", "say which way to turn"),
        ("move forward", "mobile", "say how far"),
        ("turn 400 degrees left", "mobile", "at most 360 degrees"),
        ("move forward 30 m", "mobile", "at most 20 m"),
        ("turn 90 degrees around", "mobile", "not both"),
    ],
)
def test_base_motions_are_refused_where_they_do_not_apply(text, robot, why):
    with pytest.raises(ParseError, match=why):
        parse_instruction(text, robot)


def test_the_arm_still_reads_forward_as_north():
    from tabletop.language.codegen import instruction_to_code

    assert "robot.move_north(0.1)" in instruction_to_code("move forward 10 cm")
    assert "robot.move_south(0.05)" in instruction_to_code("go back 5 cm")


@pytest.mark.parametrize(
    "text, action",
    [
        # hedges before a relation
        ("move a bit to the left of the soccer ball", Side("left", "soccer ball")),
        ("go slightly behind the mug", Side("behind", "mug")),
        (
            "go somewhere between the mug and the tray",
            Between(Goal(Part("obj", "mug")), Goal(Part("obj", "tray"))),
        ),
        # a sound named by what made it, without "the sound of"
        (
            "go to the cube closest to the dog barking",
            GoTo(Goal(Part("obj", "cube"), (Part("sound", "dog barking"),))),
        ),
        ("go to the source of the barking", GoTo(Goal(Part("sound", "barking")))),
        (
            "find the thing that sounded like a cat and go there",
            GoTo(Goal(Part("sound", "cat"))),
        ),
        # words that pick without describing
        (
            "go to whichever mug is closest to the alarm clock sound",
            GoTo(Goal(Part("obj", "mug"), (Part("sound", "alarm clock"),))),
        ),
        # a side of the table said short, or with "hand"
        (
            "go to the blue block on the left",
            GoTo(Goal(Part("obj", "blue block"), (Part("area", "left side of the table"),))),
        ),
        (
            "go to the mug on the right hand side of the table",
            GoTo(Goal(Part("obj", "mug"), (Part("area", "right side of the table"),))),
        ),
        # a relation to an object that a sound or another object singles out
        (
            "please move in front of the blue mug that is near the crying baby",
            Side("front", Goal(Part("obj", "blue mug"), (Part("sound", "crying baby"),))),
        ),
        (
            "go to the right of the bowl near the sound of a cat",
            Side("right", Goal(Part("obj", "bowl"), (Part("sound", "cat"),))),
        ),
        # a place without a verb, "next to" as the motion, "that's closest to"
        ("I want you at the left of the yellow duck", Side("left", "yellow duck")),
        ("I'd like you behind the tray", Side("behind", "tray")),
        ("go next to the bowl", GoTo(Goal(Part("obj", "bowl")))),
        (
            "find the cup that's closest to where the phone rang",
            GoTo(Goal(Part("obj", "cup"), (Part("sound", "phone rang"),))),
        ),
        # a sound told by what was making it, or by its verb alone
        ("head to whatever is making the ticking noise", GoTo(Goal(Part("sound", "ticking")))),
        ("move the hand towards the thing that was meowing", GoTo(Goal(Part("sound", "meowing")))),
        (
            "go to the purple thing near the clapping",
            GoTo(Goal(Part("obj", "purple thing"), (Part("sound", "clapping"),))),
        ),
        # a corner of the table, with or without "of the table"
        (
            "move to the far left corner of the table",
            GoTo(Goal(Part("area", "far left corner of the table"))),
        ),
        (
            "go to the front right corner",
            GoTo(Goal(Part("area", "front right corner of the table"))),
        ),
    ],
)
def test_wording_people_use(text, action):
    assert only(text).action == action


def test_an_object_is_not_a_sound_for_its_last_word_alone():
    # "ringing" names a sound, but only after what rang; a lone object stays an object
    assert only("go to the ring").action == GoTo(Goal(Part("obj", "ring")))
    assert only("go to the playing card").action == GoTo(Goal(Part("obj", "playing card")))
    # a base has no single table: "on the left" is not a table side there
    with pytest.raises(ParseError):
        parse_instruction("go to the blue block on the left", robot="mobile")
