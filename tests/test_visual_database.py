"""The reference frames (tabletop/mapping/visual/database.py): online and batch building agree,
and their persistence inside the map file round-trips and names what is corrupted."""

import json

import numpy as np
import pytest
from helpers import visual_scene

from tabletop.mapping.avlmap import AVLMap
from tabletop.mapping.visual import VisualDatabaseError, build_visual_database


@pytest.fixture(scope="module")
def rec():
    return visual_scene()[0]


@pytest.fixture(scope="module")
def queries():
    """Image goals of the scan's objects: (goal, object label)."""
    return visual_scene()[1]


@pytest.fixture(scope="module")
def avlmap():
    return visual_scene()[2]


def test_online_and_batch_reference_frames_agree(avlmap, rec):
    batch = build_visual_database(rec, avlmap.config.visual.localization)
    (h_map, a_map), (h_batch, a_batch) = avlmap.visual.state(), batch.state()
    assert h_map == h_batch
    for k in a_map:
        np.testing.assert_array_equal(a_map[k], a_batch[k], err_msg=k)


def test_save_load_round_trip_and_corrupted_visual_arrays(avlmap, queries, tmp_path):
    path = avlmap.save(tmp_path / "map.npz")
    back = AVLMap.load(path)
    assert back.config.visual == avlmap.config.visual
    (h0, a0), (h1, a1) = avlmap.visual.state(), back.visual.state()
    assert h0 == h1 and all(np.array_equal(a0[k], a1[k]) for k in a0)
    g = queries[0][0]
    np.testing.assert_array_equal(
        back.image_heatmap(g.image).values, avlmap.image_heatmap(g.image).values
    )

    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}

    def corrupt(name, **change):
        bad = {**arrays, **change}
        np.savez(tmp_path / name, **bad)
        return tmp_path / name

    offsets = arrays["visual_keypoint_offsets"].copy()
    offsets[-1] += 7
    with pytest.raises(VisualDatabaseError, match=r"bad1\.npz: visual database keypoint_offsets"):
        AVLMap.load(corrupt("bad1.npz", visual_keypoint_offsets=offsets))
    short = arrays["visual_descriptors"][:-1]
    with pytest.raises(VisualDatabaseError, match="'descriptors' has shape"):
        AVLMap.load(corrupt("bad2.npz", visual_descriptors=short))
    # A version 1 file (before the visual module) loads; its image goals are not found.
    header = json.loads(arrays["header"].tobytes())
    v1 = {k: v for k, v in arrays.items() if not k.startswith("visual_")}
    v1_header = {k: v for k, v in header.items() if k not in ("visual", "fingerprints")}
    v1_header |= {"version": 1}
    v1["header"] = np.frombuffer(json.dumps(v1_header).encode(), np.uint8)
    np.savez(tmp_path / "v1.npz", **v1)
    old = AVLMap.load(tmp_path / "v1.npz")
    h = old.image_heatmap(g.image)
    assert old.visual is None and not h.found and "no visual localization" in h.reason
    no_points = {k: v for k, v in arrays.items() if k != "visual_points_world"}
    np.savez(tmp_path / "bad3.npz", **no_points)
    with pytest.raises(VisualDatabaseError, match="array 'points_world' is missing"):
        AVLMap.load(tmp_path / "bad3.npz")
