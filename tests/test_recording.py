"""Recording format: exact round trip, validation, clear errors for missing/truncated files."""

import json

import numpy as np
import pytest

from tabletop.errors import RecordingError
from tabletop.recording import Recording, Segment, load_recording, save_recording


def make_recording(n=5, h=240, w=320, seed=0, with_extras=True):
    rng = np.random.default_rng(seed)
    res = 1e-4
    depth = np.round(rng.uniform(0.1, 2.0, (n, h, w)) / res) * res
    depth[:, :10] = 0.0
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, 3] = rng.normal(size=(n, 3))
    return Recording(
        timestamps=np.arange(n) / 30.0,
        rgb=rng.integers(0, 256, (n, h, w, 3), dtype=np.uint8),
        depth=depth.astype(np.float32),
        joint_positions=rng.normal(size=(n, 7)),
        T_world_hand=T,
        K=np.array([[200.0, 0, 159.5], [0, 200.0, 119.5], [0, 0, 1]]),
        T_hand_cam=np.eye(4),
        depth_resolution=res,
        audio=rng.normal(0, 0.1, 16000).astype(np.float32) if with_extras else None,
        audio_rate=16000,
        segments=(
            Segment("mapping", "mapping", 0, n - 1),
            Segment("episode_0", "episode", n - 1, n),
        ),
        segmentation=rng.integers(0, 20, (n, h, w), dtype=np.uint16) if with_extras else None,
        T_world_hand_true=T.copy() if with_extras else None,
        ground_truth={"objects": [{"name": "red_mug"}]} if with_extras else None,
        meta={"source": "test"},
    )


def assert_same(a: Recording, b: Recording):
    for name in (
        "timestamps",
        "rgb",
        "depth",
        "joint_positions",
        "T_world_hand",
        "K",
        "T_hand_cam",
    ):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype, name
        assert np.array_equal(x, y), name
    for name in ("audio", "segmentation", "T_world_hand_true"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert x.dtype == y.dtype and np.array_equal(x, y), name
    assert a.segments == b.segments
    assert a.ground_truth == b.ground_truth
    assert a.meta == b.meta
    assert a.audio_rate == b.audio_rate and a.depth_resolution == b.depth_resolution
    assert a.ee_frame == b.ee_frame and a.joint_names == b.joint_names


@pytest.mark.parametrize("extras", [True, False])
def test_round_trip_is_exact(tmp_path, extras):
    rec = make_recording(with_extras=extras)
    save_recording(rec, tmp_path / "rec")
    assert_same(rec, load_recording(tmp_path / "rec"))


def test_a_wheeled_base_recording_round_trips_with_its_two_wheels(tmp_path):
    rec = make_recording()
    kw = {**vars_of(rec), "joint_positions": rec.joint_positions[:, :2]}
    kw.update(ee_frame="base_footprint", joint_names=("left", "right"))
    base = Recording(**kw)
    save_recording(base, tmp_path / "rec")
    back = load_recording(tmp_path / "rec")
    assert_same(base, back)
    assert back.joint_positions.shape == (5, 2) and back.ee_frame == "base_footprint"
    with pytest.raises(RecordingError, match="joint_names has 3 names for 2 joints"):
        Recording(**{**kw, "joint_names": ("a", "b", "c")})
    with pytest.raises(RecordingError, match="J >= 1"):
        Recording(**{**kw, "joint_positions": np.zeros((5, 0))})


def test_missing_file_is_named(tmp_path):
    save_recording(make_recording(), tmp_path / "rec")
    (tmp_path / "rec" / "depth" / "000003.png").unlink()
    with pytest.raises(RecordingError, match=r"depth/000003\.png is missing"):
        load_recording(tmp_path / "rec")


def test_truncated_file_is_named(tmp_path):
    save_recording(make_recording(), tmp_path / "rec")
    f = tmp_path / "rec" / "rgb" / "000001.png"
    f.write_bytes(f.read_bytes()[:100])
    with pytest.raises(RecordingError, match=r"rgb/000001\.png has 100 bytes.*truncated"):
        load_recording(tmp_path / "rec")


def test_truncated_poses_are_named(tmp_path):
    save_recording(make_recording(), tmp_path / "rec")
    f = tmp_path / "rec" / "poses.npz"
    f.write_bytes(f.read_bytes()[:-50])
    with pytest.raises(RecordingError, match=r"poses\.npz"):
        load_recording(tmp_path / "rec")


def test_header_problems_are_clear(tmp_path):
    with pytest.raises(RecordingError, match=r"recording\.json is missing"):
        load_recording(tmp_path)
    save_recording(make_recording(n=2), tmp_path / "rec")
    header = tmp_path / "rec" / "recording.json"
    h = json.loads(header.read_text())
    h["version"] = 99
    header.write_text(json.dumps(h))
    with pytest.raises(RecordingError, match="version 99 is not supported"):
        load_recording(tmp_path / "rec")
    header.write_text("{not json")
    with pytest.raises(RecordingError, match="not valid JSON"):
        load_recording(tmp_path / "rec")


def test_save_refuses_to_overwrite_and_replaces_atomically(tmp_path):
    rec = make_recording(n=2)
    save_recording(rec, tmp_path / "rec")
    with pytest.raises(RecordingError, match="exists; pass overwrite=True"):
        save_recording(rec, tmp_path / "rec")
    other = make_recording(n=3, seed=1)
    save_recording(other, tmp_path / "rec", overwrite=True)
    assert len(load_recording(tmp_path / "rec")) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec"]  # no temporaries left


def test_overwrite_never_replaces_what_is_not_a_recording(tmp_path):
    photos = tmp_path / "photos"
    photos.mkdir()
    (photos / "holiday.jpg").write_bytes(b"not ours")
    note = tmp_path / "note.txt"
    note.write_text("mine")
    rec = make_recording(n=2)
    for path in (photos, note):
        with pytest.raises(RecordingError, match="is not a recording.*only replaces a previous"):
            save_recording(rec, path, overwrite=True)
    assert (photos / "holiday.jpg").read_bytes() == b"not ours" and note.read_text() == "mine"


def test_failed_save_leaves_nothing_behind(tmp_path):
    rec = make_recording(n=2)
    bad = Recording(**{**vars_of(rec), "depth": np.full((2, 240, 320), 9.0, np.float32)})
    with pytest.raises(RecordingError, match="does not fit 16 bits"):
        save_recording(bad, tmp_path / "rec")
    assert list(tmp_path.iterdir()) == []


def vars_of(rec):
    return {k: getattr(rec, k) for k in rec.__dataclass_fields__}


def test_validation_names_the_array():
    rec = make_recording(n=2, with_extras=False)
    with pytest.raises(RecordingError, match="joint_positions has 3 frames"):
        Recording(**{**vars_of(rec), "joint_positions": np.zeros((3, 7))})
    with pytest.raises(RecordingError, match="strictly increasing"):
        Recording(**{**vars_of(rec), "timestamps": np.array([0.0, 0.0])})
    with pytest.raises(RecordingError, match=r"T_world_hand must have shape \(N, 4, 4\)"):
        Recording(**{**vars_of(rec), "T_world_hand": np.zeros((2, 3, 4))})
    with pytest.raises(RecordingError, match="segment 'mapping'"):
        Recording(**{**vars_of(rec), "segments": (Segment("mapping", "mapping", 0, 9),)})


def test_arrays_are_read_only_copies():
    rec = make_recording(n=2, with_extras=False)
    rec = Recording(**{**vars_of(rec), "segments": ()})
    rgb = np.zeros((2, 240, 320, 3), np.uint8)
    rec2 = Recording(**{**vars_of(rec), "rgb": rgb})
    rgb[0, 0, 0, 0] = 7
    assert rec2.rgb[0, 0, 0, 0] == 0
    with pytest.raises(ValueError):
        rec2.rgb[0, 0, 0, 0] = 1
    f = rec2.frame(0)
    np.testing.assert_array_equal(f.T_world_cam, rec2.T_world_hand[0] @ rec2.T_hand_cam)
    with pytest.raises(IndexError, match="out of range"):
        rec2.frame(5)


def _with(rec, **changes):
    return Recording(**{**vars_of(rec), **changes})


def _poses(rec, fn):
    T = np.array(rec.T_world_hand)
    fn(T)
    return T


@pytest.mark.parametrize(
    "change, needle",
    [
        (
            lambda r: {"timestamps": np.array([0, np.nan, 0.2, 0.3, 0.4])},
            "timestamps must be finite",
        ),
        (lambda r: {"timestamps": np.array([0, 0.1, 0.1, 0.3, 0.4])}, "frame 2 (0.1 s) does not"),
        (lambda r: {"depth_resolution": 0.0}, "depth_resolution must be in [1e-6, 0.01]"),
        (lambda r: {"depth_resolution": float("nan")}, "depth_resolution must be in"),
        (
            lambda r: {"T_world_hand": _poses(r, lambda T: T[3, :3, 3].__iadd__(1e6))},
            "within 100 m of the base frame (a unit error?); frame 3",
        ),
        (
            lambda r: {"T_world_hand": _poses(r, lambda T: T[1, :3, :3].__imul__(2.0))},
            "T_world_hand must be a rigid transform",
        ),
        (
            lambda r: {"T_world_hand": _poses(r, lambda T: T.__setitem__((2, 0, 3), np.inf))},
            "T_world_hand must be finite; frame 2",
        ),
        (lambda r: {"T_hand_cam": np.diag([1.0, 1.0, -1.0, 1.0])}, "T_hand_cam must be a rigid"),
        (lambda r: {"K": np.array([[0.0, 0, 1], [0, 1, 1], [0, 0, 1]])}, "K must be a pinhole"),
        (lambda r: {"joint_positions": np.full((5, 7), np.nan)}, "joint_positions must be finite"),
        (lambda r: {"audio_rate": 0}, "audio_rate must be an integer in [1000, 384000]"),
        (lambda r: {"audio_rate": 16000.5}, "audio_rate must be an integer"),
    ],
)
def test_bad_recordings_are_refused_with_the_field_named(change, needle):
    rec = make_recording()
    with pytest.raises(RecordingError) as e:
        _with(rec, **change(rec))
    assert needle in str(e.value)


def _rewrite_header(path, fn):
    header = path / "recording.json"
    h = json.loads(header.read_text())
    fn(h)
    header.write_text(json.dumps(h))


@pytest.mark.parametrize(
    "fn, needle",
    [
        (lambda h: h.update(n_frames="5"), "n_frames is '5'; valid: an integer"),
        (lambda h: h.update(n_frames=-1), "n_frames is -1"),
        (lambda h: h.update(width=3.5), "width is 3.5; valid: an integer in [1, 8192] px"),
        (lambda h: h.update(K=[[1, 2], [3, 4]]), "K is [[1, 2], [3, 4]]; valid: a 3x3 list"),
        (lambda h: h.update(T_hand_cam="eye"), "T_hand_cam is 'eye'"),
        (lambda h: h.update(depth_resolution=0), "depth_resolution is 0; valid: a number"),
        (lambda h: h.update(files=["rgb/000000.png"]), "files is ['rgb/000000.png']"),
        (lambda h: h["files"].update({"../../etc/passwd": 1}), "valid: paths inside"),
        (lambda h: h.update(segments=[{"name": "x"}]), "segments is [{'name': 'x'}]"),
        (lambda h: h.update(segments="all"), "valid: a list of {name, kind, start, stop}"),
        (lambda h: h["audio"].update(file="../x.npy"), "audio is"),
        (lambda h: h["audio"].update(sample_rate="16k"), "audio is"),
        (lambda h: h.update(meta=[1]), "meta is [1]; valid: an object or null"),
        (lambda h: h.update(has_segmentation="yes"), "has_segmentation is 'yes'"),
        (lambda h: h["segments"][0].update(stop=99), "segment 'mapping' [0, 99) outside 0..5"),
        (lambda h: h["segments"][0].update(start=4, stop=2), "[4, 2) is empty or reversed"),
    ],
)
def test_malformed_headers_are_named_before_any_file_is_read(tmp_path, fn, needle):
    path = save_recording(make_recording(), tmp_path / "rec")
    _rewrite_header(path, fn)
    with pytest.raises(RecordingError) as e:
        load_recording(path)
    assert needle in str(e.value), str(e.value)


def test_a_poses_file_with_fewer_frames_than_the_header_is_named(tmp_path):
    rec = make_recording()
    path = save_recording(rec, tmp_path / "rec")
    np.savez(
        path / "poses.npz",
        timestamps=rec.timestamps[:3],
        joint_positions=rec.joint_positions,
        T_world_hand=rec.T_world_hand,
    )
    _rewrite_header(
        path, lambda h: h["files"].update({"poses.npz": (path / "poses.npz").stat().st_size})
    )
    with pytest.raises(RecordingError, match=r"timestamps has shape \(3,\), the header 5 frames"):
        load_recording(path)


def test_audio_whose_sample_rate_disagrees_with_the_frames_span_is_refused(tmp_path):
    rec = make_recording()
    rec = _with(rec, timestamps=np.arange(5) * 3.0, audio=np.zeros(12 * 16000, np.float32))
    save_recording(rec, tmp_path / "r")
    load_recording(tmp_path / "r")  # 12 s of audio, frames spanning 12 s
    _rewrite_header(tmp_path / "r", lambda h: h["audio"].update(sample_rate=8000))
    with pytest.raises(RecordingError, match=r"sample_rate 8000 Hz last 24.000 s.*span 12.000 s"):
        load_recording(tmp_path / "r")


@pytest.mark.parametrize(
    "audio, needle",
    [
        (np.full(16000, 21.0, np.float32), "float samples in \\[-1, 1\\], its peak is 21"),
        (np.full(16000, 300, np.int16), "holds int16 samples; valid: float samples in \\[-1, 1\\]"),
    ],
)
def test_audio_out_of_range_or_of_integers_is_refused(tmp_path, audio, needle):
    save_recording(make_recording(), tmp_path / "r")
    np.save(tmp_path / "r" / "audio.npy", audio)
    size = (tmp_path / "r" / "audio.npy").stat().st_size
    _rewrite_header(tmp_path / "r", lambda h: h["files"].update({"audio.npy": size}))
    with pytest.raises(RecordingError, match=needle):
        load_recording(tmp_path / "r")


@pytest.mark.parametrize("name", ["audio.npy", "poses.npz"])
@pytest.mark.parametrize("content", [b"hello, not an array\n" * 3, bytes(range(256))])
def test_an_array_file_that_is_not_one_is_named_without_pickle_advice(tmp_path, name, content):
    save_recording(make_recording(), tmp_path / "r")
    (tmp_path / "r" / name).write_bytes(content)
    _rewrite_header(tmp_path / "r", lambda h: h["files"].update({name: len(content)}))
    with pytest.raises(RecordingError) as e:
        load_recording(tmp_path / "r")
    assert f"{tmp_path / 'r' / name} is not a NumPy" in str(e.value)
    assert "allow_pickle" not in str(e.value)


@pytest.mark.parametrize("kind", ["rgb", "depth", "segmentation"])
def test_a_frame_image_of_the_wrong_size_is_named_with_its_own_size(tmp_path, kind):
    import cv2

    save_recording(make_recording(), tmp_path / "r")
    f = tmp_path / "r" / kind / "000003.png"
    img = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(f), img[:200, :300])
    size = {f"{kind}/000003.png": f.stat().st_size}
    _rewrite_header(tmp_path / "r", lambda h: h["files"].update(size))
    wrong = rf"{kind}/000003.png: image is 300x200, header says 320x240"
    with pytest.raises(RecordingError, match=wrong):
        load_recording(tmp_path / "r")
