"""Named table regions: phrasings, the table fitted from a map, region heatmaps."""

import numpy as np
import pytest
from module_helpers import GRID, labelled_voxels

from tabletop.errors import ConfigError
from tabletop.mapping.table_regions import (
    EDGE_MARGIN_M,
    ROBOT_CLEARANCE_M,
    TableFit,
    fit_table,
    region_heatmap,
)
from tabletop.mapping.targets import max_position
from tabletop.reader.place_words import parse_region


@pytest.mark.parametrize(
    ("text", "lateral", "depth"),
    [
        ("the left side of the table", "left", None),
        ("right", "right", None),
        ("the front of the table", None, "far"),
        ("the far end", None, "far"),
        ("back of the table", None, "near"),
        ("near the robot", None, "near"),
        ("the robot's side of the table", None, "near"),
        ("the arm's end", None, "near"),
        ("the side opposite the robot", None, "far"),
        ("the far right corner, opposite the robot", "right", "far"),
        ("the center of the table", "middle", "middle"),
        ("the middle", "middle", "middle"),
        ("the midpoint of the tabletop", "middle", "middle"),
        ("the very heart of the table", "middle", "middle"),
        ("right in the middle of the table", "middle", "middle"),  # stress, not a side
        ("the midpoint of the right side", "right", "middle"),
        ("the far right corner", "right", "far"),
        ("back left corner", "left", "near"),
        ("the middle of the left side", "left", "middle"),
        # "you" is the robot asked; "away", "patch" and the like name no direction
        ("the half closest to you", None, "near"),
        ("the side where you stand", None, "near"),
        ("your left", "left", None),
        ("the part of the table farthest away", None, "far"),
        ("the patch on the right", "right", None),
        ("the core of the table", "middle", "middle"),
        ("the mid part", "middle", "middle"),
        ("over on the left", "left", None),
        ("the right-most third", "right", None),
        ("towards the rear", None, "near"),
        # one-word "lefthand", the sailor's sides, stressed and "-most" middles, margins
        ("the lefthand area", "left", None),
        ("the starboard side", "right", None),
        ("port", "left", None),
        ("the slap-bang centre", "middle", "middle"),
        ("smack dab in the middle", "middle", "middle"),
        ("the centremost part", "middle", "middle"),
        ("the back margin", None, "near"),
        ("the stretch along the back", None, "near"),
        ("the frontmost part", None, "far"),
        ("the area up front", None, "far"),
        ("the rearmost bit of the table", None, "near"),
        ("the centre of it all", "middle", "middle"),
        # pointing words name no place of their own
        ("the right side over there", "right", None),
        ("the front bit here please", None, "far"),
        ("the part off to the right", "right", None),
        ("the middle of the whole table", "middle", "middle"),
        # the arm's base is the robot; just ahead of the robot is by it, ahead of it is the front
        ("the part of the table farthest from the arm's base", None, "far"),
        ("the end by the robot's base", None, "near"),
        ("the strip right in front of the robot", None, "near"),
        ("the bit just in front of you", None, "near"),
        ("the half in front of the robot", None, "far"),
        ("the left side out in front of the robot", "left", "far"),
        # the robot's viewpoint names nothing more; its own end, where it is mounted, the
        # sides of it, and past the middle
        ("the left-hand end as the robot sees it", "left", None),
        ("the far corner on the right as seen from the arm", "right", "far"),
        ("from your point of view, the left side", "left", None),
        ("the robot's own end of the table", None, "near"),
        ("the strip just by where the arm is mounted", None, "near"),
        ("the part where the robot is bolted", None, "near"),
        ("the section to the right of the robot", "right", None),
        ("the area to the left-hand side of the arm", "left", None),
        ("the stretch beyond the middle away from the base", None, "far"),
        ("the bit past the centre", None, "far"),
        ("the part this side of the middle", None, "near"),
        # a direction made an adjective or hedged, and the side across from the robot
        ("the lefty corner", "left", None),
        ("the right-ish half", "right", None),
        ("the centre-ish bit", "middle", "middle"),
        ("the part of the table across from the robot", None, "far"),
        ("the edge across the table from you", None, "far"),
    ],
)
def test_geometric_phrasings(text, lateral, depth):
    r = parse_region(text)
    assert r is not None and (r.lateral, r.depth) == (lateral, depth)


@pytest.mark.parametrize(
    "text",
    [
        "the tray area",
        "where the toys are",
        "left of the mug",
        "the moon",
        "left and right",
        "over there by the mug",
        "the right side of the mug",
        "past the mug",
    ],
)
def test_other_phrasings_are_not_geometry(text):
    assert parse_region(text) is None


def test_the_table_is_fitted_from_the_map():
    vm = labelled_voxels({"red mug": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.10))})
    fit = fit_table(GRID, vm.indices)
    assert fit is not None and abs(fit.z - 0.005) < 0.006  # the slab spans z 0..1 cm
    np.testing.assert_allclose(fit.x, (0.0, 0.6), atol=0.011)
    np.testing.assert_allclose(fit.y, (-0.3, 0.3), atol=0.011)
    assert fit_table(GRID, vm.indices[:50]) is None  # no surface to speak of


def test_regions_divide_the_usable_table_and_heat_their_rectangle():
    fit = TableFit(0.0, (0.0, 0.6), (-0.3, 0.3), 1000)
    (x0, x1), (y0, y1) = fit.usable()
    assert x0 == ROBOT_CLEARANCE_M and x1 == pytest.approx(0.6 - EDGE_MARGIN_M)
    assert (y0, y1) == pytest.approx((-0.3 + EDGE_MARGIN_M, 0.3 - EDGE_MARGIN_M))
    xs, ys = fit.box(parse_region("the far left corner"))
    assert xs == pytest.approx(((x0 + x1) / 2, x1)) and ys == pytest.approx(
        (y1 - (y1 - y0) / 3, y1)
    )
    h = region_heatmap(GRID, fit, "far left", parse_region("far left"), 10.0)
    assert h.found and h.confidence == 1.0 and h.evidence is None
    p = max_position(h, np.zeros(GRID.shape, bool))
    np.testing.assert_allclose(p[:2], [np.mean(xs), np.mean(ys)], atol=0.011)
    assert p[2] == 0.0  # on the table
    missing = region_heatmap(GRID, None, "left", parse_region("left"), 10.0)
    assert not missing.found and "no table surface" in missing.reason
    with pytest.raises(ConfigError, match="no usable part"):
        TableFit(0.0, (0.0, 0.2), (-0.3, 0.3), 10).usable()


def test_hand_sides_extremes_and_the_arm_are_geometry():
    from tabletop.reader.place_words import parse_region

    for text, want in [
        ("the left-hand side of the table", ("left", None)),
        ("the rightmost part", ("right", None)),
        ("the area nearest the arm", (None, "near")),
        ("the table's far side", (None, "far")),
        ("the furthest end from the robot", (None, "far")),
        ("at the back", (None, "near")),
        ("the right wing of the table", ("right", None)),
        ("the side where the robot stands", (None, "near")),
        ("the part of the table where the arm sits", (None, "near")),
        ("the robot's right", ("right", None)),
        ("the arm's left-hand side", ("left", None)),
    ]:
        r = parse_region(text)
        assert r is not None and (r.lateral, r.depth) == want, text
    for text in (
        "left of the mug",
        "the area around the tray",
        "the left arm of the bear",
        "the tray wing",
        "where the mug is",
    ):
        assert parse_region(text) is None, text


def test_area_subject_names_the_object_a_place_is_named_after():
    from tabletop.reader.place_words import area_subject

    assert area_subject("the area around the tray") == "tray"
    assert area_subject("the spot by the blue mug") == "blue mug"
    assert area_subject("where the toys are") == "toys"
    assert area_subject("over there by the mug") == "mug"
    assert area_subject("the left side of the table") is None
    assert area_subject("the area") is None
