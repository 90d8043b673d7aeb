"""The map search (tabletop/mapping/visual/panorama.py): its poses are upright cameras in the
eval's image convention, its settings are checked, and the check's colour rarity counts what
the map holds."""

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.eval.images import view_pose
from tabletop.eval.tasks import ImageView
from tabletop.grid import VoxelGrid
from tabletop.mapping.visual import PhotometricCheck, VisualLocalizationConfig
from tabletop.mapping.visual.panorama import PanoramaSearch, upright_pose


@pytest.mark.parametrize("yaw_deg, pitch_deg", [(0, 0), (90, -20), (-135, -40), (200, 10)])
def test_an_upright_pose_looks_where_an_upright_view_looks(yaw_deg, pitch_deg):
    yaw, pitch = np.radians(yaw_deg), np.radians(pitch_deg)
    eye = np.array([1.0, 2.0, 1.1])
    d = np.array([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), np.sin(pitch)])
    view = ImageView(eye=tuple(eye), look_at=tuple(eye + d), up=(0.0, 0.0, 1.0))
    np.testing.assert_allclose(upright_pose(eye, pitch, yaw), view_pose(view), atol=1e-9)


def test_search_settings_are_checked():
    for kw, word in [
        ({"search_step_m": 0}, "search_step_m"),
        ({"search_pitch_min_deg": 20, "search_pitch_max_deg": 10}, "search_pitch_min_deg"),
        ({"search_min_kappa": 1.5}, "search_min_kappa"),
        ({"search_weak_rare_agreement": -0.2}, "search_weak_rare_agreement"),
        ({"search_rare_share": -0.1}, "search_rare_share"),
        ({"search_candidates": 0}, "search_candidates"),
    ]:
        with pytest.raises(ConfigError, match=word):
            VisualLocalizationConfig(**kw)


def _room():
    """A 3 x 3 m floor (grey) with a red box standing on it: the places, their panoramas."""
    grid = VoxelGrid(lower=(0.0, 0.0, -0.03), upper=(3.0, 3.0, 1.5), voxel_size=0.05)
    ij = np.argwhere(np.ones(grid.shape[:2], bool))
    floor = np.column_stack([ij, np.zeros(len(ij), int)])
    box = np.argwhere(np.ones((4, 4, 8), bool)) + np.array([28, 28, 1])  # 1.4-1.6 m, to 0.4 m
    idx = np.concatenate([floor, box])
    rgb = np.concatenate(
        [np.tile([(120, 120, 120)], (len(floor), 1)), np.tile([(200, 30, 30)], (len(box), 1))]
    ).astype(np.uint8)
    return grid, idx, rgb


def test_places_are_free_floor_and_rare_colours_are_the_objects():
    grid, idx, rgb = _room()
    search = PanoramaSearch(grid, idx, rgb, 1.1, VisualLocalizationConfig(search_step_m=0.25))
    assert len(search) > 50 and np.all(search.positions[:, 2] == 1.1)
    # no place within the clearance of the box
    near = np.abs(search.positions[:, :2] - 1.5).max(axis=1) < 0.1 + 0.15
    assert not near.any()
    assert search.panoramas.shape == (len(search), search.elevations, search.azimuths, 3)
    check = PhotometricCheck(grid, idx, rgb)
    common = check.commonness(np.array([(120, 120, 120), (200, 30, 30), (30, 30, 200)]), 40.0)
    assert common[0] > 0.9 and 0 < common[1] < 0.05 and common[2] == 0.0
    with pytest.raises(ConfigError, match="camera_height"):
        PanoramaSearch(grid, idx, rgb, float("nan"))


def _tiled_room():
    """A 3 x 3 m floor of 30 cm tiles in random colours with three coloured boxes on it."""
    rng = np.random.default_rng(3)
    grid = VoxelGrid(lower=(0.0, 0.0, -0.03), upper=(3.0, 3.0, 1.5), voxel_size=0.05)
    ij = np.argwhere(np.ones(grid.shape[:2], bool))
    tiles = rng.integers(40, 220, size=(10, 10, 3))
    idx = [np.column_stack([ij, np.zeros(len(ij), int)])]
    rgb = [tiles[ij[:, 0] // 6, ij[:, 1] // 6]]
    for corner, colour in [
        ((10, 40), (220, 20, 20)),
        ((40, 12), (20, 200, 40)),
        ((45, 45), (240, 220, 10)),
    ]:
        box = np.argwhere(np.ones((5, 5, 10), bool)) + np.array([*corner, 1])
        idx.append(box)
        rgb.append(np.tile([colour], (len(box), 1)))
    return grid, np.concatenate(idx), np.concatenate(rgb).astype(np.uint8)


def _view_of_map(check, T, K, w=320, h=240, every=4):
    """What the map shows from ``T``: every ``every``-th pixel marched, blown up to (h, w)."""
    v, u = np.mgrid[every // 2 : h : every, every // 2 : w : every]
    hit, first = check._first_colours(T, K, u.ravel(), v.ravel())
    small = np.full((u.size, 3), 255.0)  # sky: white
    small[hit] = first
    small = small.reshape(*u.shape, 3).astype(np.uint8)
    return np.repeat(np.repeat(small, every, axis=0), every, axis=1)


def test_refinement_brings_a_grid_pose_back_to_where_the_image_was_taken():
    grid, idx, rgb = _tiled_room()
    check = PhotometricCheck(grid, idx, rgb)
    K = np.array([[260.0, 0, 160], [0, 260.0, 120], [0, 0, 1]])
    truth = upright_pose((0.6, 0.7, 1.1), np.radians(-30), np.radians(40))
    image = _view_of_map(check, truth, K)
    config = VisualLocalizationConfig()
    # a grid pose a decimetre and a few degrees off, as the map search gives them
    start = upright_pose((0.7, 0.62, 1.1), np.radians(-25), np.radians(43))
    refined, tries = check.refine_upright(start, K, image, config)
    before, after = (check.details(T, K, image, config) for T in (start, refined))
    assert before["kappa"] < 0.3 and after["kappa"] > 0.7
    # nearer the truth; looking where the image looks (height and pitch trade off a little
    # over a flat floor)
    assert np.linalg.norm(refined[:2, 3] - truth[:2, 3]) < np.linalg.norm(
        start[:2, 3] - truth[:2, 3]
    )

    def angle(T):
        return np.degrees(np.arccos(np.clip(T[:3, 2] @ truth[:3, 2], -1.0, 1.0)))

    assert angle(refined) < 0.7 * angle(start)
    assert 1 < tries <= 120
    # the refined pose stays upright (no roll): its x axis is horizontal
    assert abs(refined[2, 0]) < 1e-9


def test_a_weak_matched_pose_gives_way_to_a_searched_pose_that_reproduces_more():
    from tabletop.mapping.visual.localize import SEARCH_OVERRULES_BY, _better_searched, _checked

    grid, idx, rgb = _tiled_room()
    check = PhotometricCheck(grid, idx, rgb)
    config = VisualLocalizationConfig(search=True, min_agreement=0.3, min_kappa=0.2)
    search = PanoramaSearch(grid, idx, rgb, 1.1, config)
    K = np.array([[260.0, 0, 160], [0, 260.0, 120], [0, 0, 1]])
    truth = upright_pose((0.9, 0.8, 1.1), np.radians(-30), np.radians(40))
    image = _view_of_map(check, truth, K)

    def matched(T):
        return _checked(
            {"T": T, "inliers": 20, "matches": 30, "references": ()}, check, image, K, config
        )

    # a pose 15 cm off that a few matches support and the plain check lets through
    wrong = matched(upright_pose((0.75, 0.8, 1.1), np.radians(-30), np.radians(40)))
    assert wrong["T"] is not None and wrong["agreement"] < 0.6
    better = _better_searched(lambda: search, check, image, K, config, wrong)
    assert better is not None and better["searched"]
    assert better["agreement"] >= wrong["agreement"] + SEARCH_OVERRULES_BY
    err = np.linalg.norm(better["T"][:2, 3] - truth[:2, 3])
    assert err < 0.5 * np.linalg.norm(wrong["T"][:2, 3] - truth[:2, 3])
    # the true pose itself is not overruled
    assert _better_searched(lambda: search, check, image, K, config, matched(truth)) is None
