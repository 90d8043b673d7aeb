"""The web viewer (``tabletop view``, the optional ``viewer`` extra): what it draws, its
queries through the robot's reader and query layer, its reaches, and the page itself in a real
headless browser (Chromium through selenium, WebGL in software).

The map is the six-frame synthetic table of ``test_hardening_honest`` (a box on the default
table, the default scene's spec as its ground truth), coloured here in two plain colours so that
a screenshot can tell the map from the page: a tan table and a blue box. The browser tests skip,
saying why, where viser, selenium, chromium or chromedriver is missing.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
import pytest
from test_hardening_honest import small_recording

from tabletop.cli import main
from tabletop.errors import ConfigError

TABLE = (205, 170, 110)
BOX = (40, 90, 210)


def coloured_recording():
    """``small_recording`` with a tan table and a blue box (its segmentation decides)."""
    from dataclasses import fields

    from tabletop.recording import Recording

    rec = small_recording()
    rgb = np.empty(rec.rgb.shape, np.uint8)
    rgb[:] = TABLE
    rgb[rec.segmentation == 4] = BOX
    kw = {f.name: getattr(rec, f.name) for f in fields(rec)}
    kw["rgb"] = rgb
    return Recording(**kw)


@pytest.fixture(scope="module")
def small_map(tmp_path_factory):
    """(map path, recording dir) of the coloured six-frame table, built by ``build-map``."""
    from tabletop.recording import save_recording

    d = tmp_path_factory.mktemp("viewer")
    rec = save_recording(coloured_recording(), d / "rec")
    assert main(["build-map", str(rec), "--out", str(d / "map.npz")]) in (0, 1)
    return d / "map.npz", rec


# --------------------------------------------------------------------------- no browser
def test_the_preview_reads_voxels_and_colours_without_the_encoders(small_map):
    from tabletop.mapping.avlmap import AVLMap
    from tabletop.mapping.persistence import read_map_preview

    p = read_map_preview(small_map[0])
    m = AVLMap.load(small_map[0])
    np.testing.assert_allclose(p.centers, m.voxels.centers)
    np.testing.assert_array_equal(p.colors, m.voxels.mean_colors())
    np.testing.assert_array_equal(p.linear, m.voxels.linear_indices)
    assert {tuple(c) for c in p.colors} <= {TABLE, BOX}


def test_the_embodiments_are_named_before_they_are_imported():
    from tabletop.grid import VoxelGrid
    from tabletop.viewer.session import ROOM_EMBODIMENTS, TABLE_EMBODIMENTS, ViewerSession

    s = object.__new__(ViewerSession)
    for room, names in ((False, TABLE_EMBODIMENTS), (True, ROOM_EMBODIMENTS)):
        s.room = room
        assert tuple(e.name for e in s.embodiments()) == s.embodiment_names() == names
    assert not is_room(VoxelGrid()) and is_room(VoxelGrid((0, 0, 0), (6, 5, 2.6), 0.05))


def is_room(grid) -> bool:
    from tabletop.viewer.session import is_room_grid

    return is_room_grid(grid)


def test_drawing_helpers():
    from tabletop.grid import VoxelGrid
    from tabletop.viewer import draw

    assert draw.box_segments([0, 0, 0], [1, 2, 3]).shape == (12, 2, 3)
    assert draw.path_segments(np.zeros((5, 3))).shape == (4, 2, 3)
    K = np.array([[200.0, 0, 160], [0, 200.0, 120], [0, 0, 1]])
    segs = draw.frustum_segments(np.stack([np.eye(4)] * 3), K, (320, 240), 0.5)
    assert segs.shape == (24, 2, 3) and np.isclose(segs[:, 1, 2].max(), 0.5)
    g = VoxelGrid(voxel_size=0.02)
    heat = np.zeros(g.shape, np.float32)
    heat[10, 10, 5] = 1.0
    heat[11, 10, 5] = 0.01  # below the floor: not drawn
    lin = g.linear(np.array([[10, 10, 5], [11, 10, 5], [0, 0, 0]]))
    pos, cols, h = draw.heat_voxels(heat, g, lin)
    assert len(pos) == 1 and h[0] == 1.0 and cols[0, 0] > 100 and cols[0, 2] < 60  # hot: red
    links = {m.link for m in draw.panda_link_meshes()}
    assert {"panda_link0", "panda_link7", "panda_hand", "panda_leftfinger"} <= links


@pytest.fixture(scope="module")
def session(small_map):
    """The small map's viewer session, loaded (shared by the page's tests)."""
    from tabletop.viewer.session import ViewerSession

    s = ViewerSession(*small_map)
    s.load()
    assert s.map is not None, s.error
    return s


def test_queries_go_through_the_reader_and_the_robot_api(session):
    s = session
    out = s.query("go to the mug")
    assert out.found and out.heat is not None and len(out.targets) == 1
    assert "move_to_object" in out.code or "get_max_pos_3d" in out.code
    assert 0.28 <= out.targets[0][0] <= 0.52  # on the box
    typed = s.query("mug", "object")
    assert typed.found and typed.parts[0].modality == "object"
    near = s.query("mug", "object", near="the middle of the table", near_kind="area")
    assert near.found, near.reason
    assert [p.modality for p in near.parts] == ["object", "area"]
    worded = s.query("the mug", "request", near="the middle of the table", near_kind="area")
    assert worded.found, worded.reason
    assert worded.text == "the mug in the middle of the table"
    missing = s.query("the giraffe")
    assert not missing.found and "giraffe" in missing.reason
    refused = s.query("xqzv wvvt", "request")
    assert not refused.found and refused.reason
    with pytest.raises(ConfigError):
        s.query("mug", "colour")


def test_the_command_names_the_extra_when_viser_is_missing(monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "viser", None)  # import viser raises ImportError
    assert main(["view", str(tmp_path / "map.npz")]) == 2  # said before the map is read
    err = capsys.readouterr().err
    assert "viewer" in err and "pip install" in err


def test_the_command_checks_its_arguments_before_serving(capsys, tmp_path):
    pytest.importorskip("viser", reason="the viewer extra is not installed")
    assert main(["view", str(tmp_path / "none.npz")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["view", str(tmp_path), "--port", "70000"]) == 2


def test_the_view_command_line_is_quoted():
    from tabletop.cli.view import view_command

    assert view_command("out/demo/m.npz", "out/demo/r", "out/demo") == (
        "tabletop view out/demo/m.npz --recording out/demo/r --eval out/demo"
    )
    assert view_command("a b.npz") == "tabletop view 'a b.npz'"


def test_the_demo_prints_the_command_that_opens_its_map(capsys):
    from pathlib import Path

    from tabletop.cli.evaluate import _print_view_command

    _print_view_command([("", ""), ("out/demo/cache/m.npz", "out/demo/cache/r")], Path("out/demo"))
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1
    assert out[0].endswith(
        "tabletop view out/demo/cache/m.npz --recording out/demo/cache/r --eval out/demo"
    )


def test_evaluation_goals_are_read_from_results_json(small_map, tmp_path):
    from tabletop.viewer.session import ViewerSession

    goal = {"goal_id": "object-mug", "type": "object", "text": "the mug", "status": "done",
            "target": [0.4, 0.0, 0.08], "tcp": [0.4, 0.0, 0.12], "truth": [[[0.28, -0.02, 0],
            [0.52, 0.02, 0.08]]]}  # fmt: skip
    tasks = [
        {"task": "x.toml", "scene": "default", "map_file": str(small_map[0]), "goals": [goal]},
        {"task": "y.toml", "scene": "other", "map_file": "elsewhere.npz", "goals": [goal]},
    ]
    res = {"rows": [{"encoders": "oracle", "tasks": tasks}]}
    (tmp_path / "results.json").write_text(json.dumps(res))
    s = ViewerSession(small_map[0], eval_dir=tmp_path)
    goals = s.eval_goals()
    assert len(goals) == 1 and goals[0].same_map and goals[0].task == "x.toml"


# --------------------------------------------------------------------------- the browser
@pytest.fixture(scope="module")
def page(session):
    """(viewer, browser) with the page open, or a skip saying why there is none."""
    pytest.importorskip("viser", reason="the viewer extra is not installed (pip install -e "
                        "'.[viewer]')")  # fmt: skip
    from tabletop.viewer.browser import HeadlessBrowser, browser_problem

    problem = browser_problem()
    if problem:
        pytest.skip(f"no headless browser here: {problem}")
    from tabletop.viewer.app import Viewer

    viewer = Viewer(session, port=0, animation_s=1.5)
    try:
        browser = HeadlessBrowser()
    except RuntimeError as e:
        viewer.close()
        pytest.skip(f"no headless browser here: {e}")
    yield viewer, browser
    browser.close()
    viewer.close()


def _hot(img: np.ndarray) -> int:
    """Pixels of the heat scheme's hot end (red), which neither map colour is."""
    r, g, b = (img[..., k].astype(int) for k in range(3))
    return int(((r > 100) & (g < 70) & (b < 70)).sum())


def test_the_page_draws_the_map_asks_it_and_reaches(page):
    from tabletop.viewer.browser import colour_share, first_picture, map_palette, wait_for

    viewer, browser = page
    t0 = time.perf_counter()
    palette = map_palette(viewer.s.preview.colors)
    first_picture(browser, viewer.url, palette, share=0.02, timeout=60)
    shot = browser.scene()
    assert shot.std() > 10  # not blank
    assert colour_share(shot, palette) >= 0.02  # the map's tan table and blue box are drawn
    assert _hot(shot) < 50

    # a query typed into the page: the heatmap appears, hot on the box
    browser.wait_enabled("Ask", timeout=90)
    browser.type_into("request", "the mug")
    # the page sends each keystroke on its own: "Ask" is pressed once the server holds them
    # all (pressed at once, it had once asked for "t")
    wait_for(lambda: viewer.t_query.value == "the mug", 30, "the typed words at the server")
    browser.button("Ask").click()
    wait_for(lambda: viewer.asked >= 1, 60, "the answer")
    assert viewer.last.found, viewer.last.reason
    wait_for(lambda: _hot(browser.scene()) > 100, 30, "the heatmap drawn")

    # a second query changes the drawn heatmap: now on a side of the table
    before = browser.scene()
    browser.type_into("request", "the left side of the table")
    wait_for(lambda: viewer.t_query.value == "the left side of the table", 30, "the typed words")
    browser.button("Ask").click()
    wait_for(lambda: viewer.asked >= 2, 60, "the second answer")
    assert viewer.last.found, viewer.last.reason
    wait_for(lambda: (np.abs(browser.scene().astype(int) - before).max(axis=2) > 60).sum()
             > 200, 30, "the heatmap redrawn")  # fmt: skip

    # "go": the arm moves in the page
    browser.wait_enabled("go", timeout=30)
    time.sleep(0.5)
    before = browser.scene()
    q0 = {n: h.position.copy() for n, h in viewer.links.items()}
    browser.button("go").click()
    wait_for(lambda: viewer.reaches >= 1, 90, "the reach")
    moved = max(np.linalg.norm(h.position - q0[n]) for n, h in viewer.links.items())
    assert moved > 0.05  # the drawn arm's links moved
    wait_for(lambda: (np.abs(browser.scene().astype(int) - before).max(axis=2) > 60).sum()
             > 500, 30, "the arm redrawn")  # fmt: skip
    assert "reached" in viewer.md_go.content
    assert time.perf_counter() - t0 < 120
