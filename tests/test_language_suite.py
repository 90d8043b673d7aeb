"""The instruction suite on its reference map: the offline parser's targets against the
hand-written expected code's targets."""

import numpy as np
import pytest

from tabletop.language import check_code, instruction_to_code
from tabletop.language.suite import (
    PointRobot,
    evaluate_suite,
    load_suite,
    reference_map,
    write_suite_images,
)


@pytest.fixture(scope="module")
def suite():
    return load_suite()


@pytest.fixture(scope="module")
def robot(suite):
    return PointRobot(reference_map(suite), suite.start)


@pytest.fixture(scope="module")
def images(suite, tmp_path_factory):
    return write_suite_images(suite, tmp_path_factory.mktemp("suite_images"))


@pytest.fixture(scope="module")
def report(robot, suite, images):
    return evaluate_suite(robot, suite=suite, image_dir=images)


def test_the_suite_covers_every_family_with_several_phrasings(suite):
    assert len(suite.cases) >= 60
    fam = suite.families
    for f in ("object", "sound", "image", "area", "near", "between", "side", "compass"):
        assert fam.get(f, 0) >= 4, f
    assert fam["sequence"] >= 4 and fam["repeat"] >= 4
    # "X near Y" for every ordered pair of modalities
    pairs = {
        c.id.split("-")[1] + "-" + c.id.split("-")[2] for c in suite.cases if c.family == "near"
    }
    for a in ("obj", "sound", "img", "area"):
        for b in ("obj", "sound", "img", "area"):
            assert f"{a}-{b}" in pairs, f"{a} near {b}"
    verbs = {c.instruction.lower().split()[0] for c in suite.cases}
    assert {"go", "move", "reach", "approach"} <= verbs
    texts = " ".join(c.instruction for c in suite.cases)
    for phrase in ("near", "next to", "close to", "where you heard", "then", "twice", "times"):
        assert phrase in texts
    for case in suite.cases:
        check_code(case.expected)


def test_the_parser_matches_the_expected_targets(report):
    misses = [(r.case.id, r.reason) for r in report.results if not r.match]
    print(f"suite share: {report.matched}/{len(report.results)} = {report.share:.1%}")
    assert misses == []
    assert report.share == 1.0
    assert all(r.error_m is not None and r.error_m <= 0.005 for r in report.results)


def test_targets_are_where_the_reference_map_puts_the_goals(report, suite):
    from tabletop.sim.scene import load_scene_spec

    spec = load_scene_spec(suite.scene)
    centre = {o.name: np.mean(o.aabb(), axis=0) for o in spec.objects}
    got = {r.case.id: r.targets for r in report.results}

    def near(p, name, tol=0.06):
        return np.linalg.norm(p[:2] - centre[name][:2]) <= tol

    # a mug: two in the scene; the sound decides which
    assert near(got["near-obj-sound-01"][0], "blue_mug")  # the dog barked at the blue mug
    assert near(got["near-obj-sound-03"][0], "red_mug")  # the alarm clock at the red one
    assert near(got["near-obj-sound-04"][0], "white_duck")
    assert near(got["image-01"][0], "brown_teddy_bear")
    assert near(got["sound-02"][0], "yellow_duck")
    mid = (centre["red_mug"] + centre["blue_mug"]) / 2
    assert np.linalg.norm(got["between-01"][0][:2] - mid[:2]) <= 0.03
    # left = +y of the red mug; a compass move adds to the previous target
    assert got["side-01"][0][1] > centre["red_mug"][1] + 0.05
    seq = got["sequence-04"]
    np.testing.assert_allclose(seq[1] - seq[0], [0.0, 0.05, 0.0], atol=1e-9)
    np.testing.assert_allclose(got["compass-01"][0], np.add(suite.start, [0.1, 0.0, 0.0]))
    assert len(got["repeat-03"]) == 4 and len(got["repeat-04"]) == 6


def test_the_score_catches_a_wrong_generator(robot, suite, images):
    """Swapping which goal is sharp (the primary) and which is broad changes the targets."""

    def swapped(text):
        code = instruction_to_code(text)
        return (
            code.replace("get_major_map", "TMP")
            .replace("get_map(", "get_major_map(")
            .replace("TMP", "get_map")
        )

    # A named table region is a plateau of heat (geometry): sharp and broad agree inside it, so
    # cases with a region cannot tell the two generators apart.
    near_cases = [c.id for c in suite.cases if c.family == "near" and "area" not in c.id]
    bad = evaluate_suite(robot, swapped, suite, image_dir=images, cases=near_cases)
    assert bad.matched < len(near_cases) // 2
    assert any("targets differ" in r.reason for r in bad.results)


def test_unknown_case_ids_are_named(robot, suite):
    with pytest.raises(Exception, match="unknown case ids \\['nope'\\]"):
        evaluate_suite(robot, suite=suite, cases=["nope"])


def test_a_malformed_suite_file_is_a_clear_error(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('[scene]\nname = "default"\nstart = [0, 0, 0]\n[[case]]\nid = "a"\n')
    with pytest.raises(Exception, match="malformed: KeyError"):
        load_suite(f)
    with pytest.raises(Exception, match="does not exist"):
        load_suite(tmp_path / "missing.toml")


def test_cases_the_map_cannot_answer_are_skipped_not_missed(robot, suite, tmp_path):
    # no goal images in this directory: the expected code of an image case fails itself
    rep = evaluate_suite(robot, suite=suite, image_dir=tmp_path, cases=["image-01", "object-01"])
    skipped = [r for r in rep.results if r.skipped]
    assert [r.case.id for r in skipped] == ["image-01"]
    assert "does not exist" in skipped[0].reason
    assert (rep.evaluated, rep.matched, rep.skipped, rep.share) == (1, 1, 1, 1.0)
