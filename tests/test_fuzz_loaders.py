"""Property-based tests of the loaders where data enter: task files, recording directories and
map files. Generated edits of a valid input (a value replaced by any JSON value, NaN and
infinities included, or a key removed; arrays made non-finite, reshaped or retyped) must end in
a valid result or the loader's typed error, never another exception."""

from __future__ import annotations

import copy
import json
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from helpers import small_recording
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tabletop.errors import TabletopError
from tabletop.eval.tasks import TaskFile, load_tasks, parse_tasks
from tabletop.recording import Recording, load_recording, save_recording

#: Generated inputs per test (the note's count: 3 tests x this).
EXAMPLES = 300
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

# ---------------------------------------------------------------------- values and edits
SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.sampled_from([0, -1, 1, 2**31, 2**63, 10**30]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([math.nan, math.inf, -math.inf, 0.0, -0.0, 1e308, 5e-324]),
    st.text(max_size=12),
    st.sampled_from(["", "../../etc/passwd", "/dev/zero", "\x00", "nan", "default", "obj"]),
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=8,
)
DELETE = object()


def _paths(obj, prefix=()):
    """Every key/index path of a JSON-like object (containers included)."""
    out = [prefix] if prefix else []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += _paths(v, (*prefix, i))
    return out


def _edit(obj, path, value):
    parent = obj
    for k in path[:-1]:
        parent = parent[k]
    if value is DELETE:
        del parent[path[-1]]
    else:
        parent[path[-1]] = value


@st.composite
def edited(draw, doc, n_max=3):
    """``doc`` with 1..n_max generated edits (replace or delete a value, add a key)."""
    d = copy.deepcopy(doc)
    for _ in range(draw(st.integers(1, n_max))):
        paths = _paths(d)
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        action = draw(st.sampled_from(["replace", "replace", "delete", "add"]))
        if action == "add":
            parent = d
            for k in path[:-1]:
                parent = parent[k]
            if isinstance(parent, dict):
                parent[draw(st.text(min_size=1, max_size=8))] = draw(VALUES)
            continue
        _edit(d, path, DELETE if action == "delete" else draw(VALUES))
    return d


# ---------------------------------------------------------------------- task files
TASK_DOC = {
    "format": "tabletop-tasks",
    "version": 1,
    "name": "fuzz",
    "scene": {"name": "default"},
    "scan": {"seed": 1, "speed": 0.45, "episodes": 4},
    "map": {"frame_step": 2},
    "noise": {"pose_translation_m": 0.005},
    "goals": [
        {
            "id": "o",
            "type": "object",
            "text": "the red mug",
            "query": {"obj": "red mug"},
            "truth": {"object": "red_mug"},
        },
        {
            "id": "a",
            "type": "ambiguous",
            "text": "the mug near the dog",
            "query": {"sound": "a dog barking", "obj": "mug"},
            "primary": "obj",
            "truth": {"object": "red_mug"},
        },
        {
            "id": "s",
            "type": "spatial",
            "text": "between",
            "relation": "between",
            "landmarks": [{"obj": "tray"}, {"obj": "red mug"}],
            "truth": {"relation": "between", "of": [{"object": "tray"}, {"object": "red_mug"}]},
        },
        {
            "id": "i",
            "type": "image",
            "text": "this image",
            "query": {"img": {"eye": [0.4, 0.3, 0.4], "look_at": [0.4, 0.3, 0.0]}},
            "truth": {"camera": [0.4, 0.3, 0.4]},
        },
        {
            "id": "n",
            "type": "absent",
            "text": "the giraffe",
            "query": {"obj": "giraffe"},
            "truth": {"absent": True},
        },
    ],
    "sequences": [{"id": "q", "goals": ["s", "o"]}],
}


def test_the_task_document_is_valid():
    tf = parse_tasks(copy.deepcopy(TASK_DOC), source="fuzz.toml")
    assert len(tf.goals) == 5 and tf.noise == {"pose_translation_m": 0.005}


def _finite_everywhere(obj) -> bool:
    if isinstance(obj, float):
        return math.isfinite(obj)
    if isinstance(obj, dict):
        return all(_finite_everywhere(v) for v in obj.values())
    if isinstance(obj, (list, tuple)):
        return all(_finite_everywhere(v) for v in obj)
    return True


@FUZZ
@given(doc=edited(TASK_DOC))
def test_edited_task_files_parse_or_raise_a_task_file_error(doc):
    try:
        tf = parse_tasks(doc, source="fuzz.toml")
    except TabletopError as e:
        assert str(e).startswith("fuzz.toml"), str(e)  # the error names the file
        return
    assert isinstance(tf, TaskFile) and tf.goals
    # what is accepted holds no NaN or infinity where the runner computes with it
    for g in tf.goals:
        assert _finite_everywhere([g.truth.point, g.truth.box])
        if g.query is not None:
            assert _finite_everywhere([v for _, v in g.query.parts if not isinstance(v, str)])
    assert _finite_everywhere(tf.noise) and _finite_everywhere(tf.scan)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(text=st.text(max_size=200))
def test_arbitrary_bytes_in_a_task_file_give_a_typed_error(text):
    with tempfile.TemporaryDirectory() as d:
        for suffix in (".toml", ".json"):
            p = Path(d) / f"t{suffix}"
            p.write_text(text)
            with pytest.raises(TabletopError):
                load_tasks(p)


# ---------------------------------------------------------------------- recordings
@pytest.fixture(scope="module")
def saved_recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzzrec") / "rec"
    save_recording(small_recording(), path)
    return path


ARRAY_EDITS = st.sampled_from(["nan", "inf", "shape", "dtype", "empty", "scalar", "huge"])


def _array_edit(a: np.ndarray, how: str) -> np.ndarray:
    a = np.array(a, dtype=np.float64)
    if a.size == 0 and how in ("nan", "inf", "shape"):
        return np.full((1, *a.shape[1:]), np.nan)  # an entry the header does not count
    if how == "nan":
        a.flat[0] = np.nan
    elif how == "inf":
        a.flat[-1] = np.inf
    elif how == "shape":
        a = a.reshape(-1)[:-1]
    elif how == "dtype":
        return a.astype("U4")
    elif how == "empty":
        return a[:0]
    elif how == "scalar":
        return np.array(1.0)
    elif how == "huge":
        a = a * 1e12
    return a


@FUZZ
@given(
    header=st.data(),
    pose_edit=st.one_of(st.none(), st.tuples(st.sampled_from(["timestamps", "joint_positions",
                                                               "T_world_hand"]), ARRAY_EDITS)),
)  # fmt: skip
def test_edited_recordings_load_or_raise_a_recording_error(saved_recording, header, pose_edit):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "rec"
        shutil.copytree(saved_recording, path)
        h = json.loads((path / "recording.json").read_text())
        if pose_edit is not None:
            name, how = pose_edit
            with np.load(path / "poses.npz") as z:
                poses = {k: z[k] for k in z.files}
            poses[name] = _array_edit(poses[name], how)
            np.savez(path / "poses.npz", **poses)
            h["files"]["poses.npz"] = (path / "poses.npz").stat().st_size
        h = header.draw(edited(h))
        (path / "recording.json").write_text(json.dumps(h))
        try:
            rec = load_recording(path)
        except TabletopError:
            return
        assert isinstance(rec, Recording) and len(rec) == h["n_frames"]
        assert np.isfinite(rec.timestamps).all() and np.isfinite(rec.T_world_hand).all()


# ---------------------------------------------------------------------- maps
@pytest.fixture(scope="module")
def saved_map(tmp_path_factory):
    """A small oracle map of a synthetic recording looking down at a labelled table."""
    from helpers import ground_truth_dict

    from tabletop.eval.harness import build_map

    rec = small_recording(4)
    T = np.array(rec.T_world_hand)
    T[:, :3, :3] = np.diag([1.0, -1.0, -1.0])  # the camera looks down at the table
    seg = np.zeros((4, 48, 64), np.uint16)
    seg[:, 16:32, 20:40] = 4  # the first ground-truth object's instance id
    truth = ground_truth_dict(
        objects=[{"name": "red_mug", "aabb_min": [0.25, -0.05, 0.0], "aabb_max": [0.35, 0.05, 0.1]}]
    )
    kw = {k: getattr(rec, k) for k in rec.__dataclass_fields__}
    kw.update(T_world_hand=T, segmentation=seg, ground_truth=truth)
    m = build_map(Recording(**kw), "oracle")
    assert m.voxels.n > 0
    return m.save(tmp_path_factory.mktemp("fuzzmap") / "map.npz")


MAP_ARRAY_EDITS = st.tuples(
    st.sampled_from(
        ["voxel_linear", "voxel_feature_sums", "voxel_counts", "voxel_color_sums",
         "voxel_instance", "frame_embeddings", "frame_poses", "segment_positions"]
    ),
    ARRAY_EDITS,
)  # fmt: skip


@FUZZ
@given(data=st.data(), array_edit=st.one_of(st.none(), MAP_ARRAY_EDITS))
def test_edited_map_files_load_or_raise_a_typed_error(saved_map, data, array_edit):
    from tabletop.mapping import AVLMap

    with np.load(saved_map) as z:
        arrays = {k: z[k] for k in z.files}
    h = json.loads(arrays.pop("header").tobytes().decode())
    if array_edit is not None:
        name, how = array_edit
        arrays[name] = _array_edit(arrays[name], how)
    else:
        h = data.draw(edited(h))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "map.npz"
        text = json.dumps(h)  # NaN from a generated value is written as JSON's extension
        np.savez(path, header=np.frombuffer(text.encode(), np.uint8), **arrays)
        try:
            m = AVLMap.load(path)
        except TabletopError:
            return
        assert m.voxels.n == len(arrays["voxel_linear"])
        assert np.isfinite(m.voxels.mean_features()).all()
