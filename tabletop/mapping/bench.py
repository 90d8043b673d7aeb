"""Map benchmarks: fusion throughput and query latency, each against a straightforward
reference measured in the same run, and the map's memory.

- Fusion reference: a per-point Python loop accumulating each point's feature into a dict of
  voxels (what a first implementation, or the official code's per-point loop, does).
- Query reference: the object heatmap computed as an O(N*M) loop over the M target voxels,
  each updating the distance of all N grid voxels (the official code's formulation).
"""

from __future__ import annotations

import time

import numpy as np

from tabletop.mapping import AVLMap, MapConfig
from tabletop.mapping.voxel_map import VoxelMap, frame_points

__all__ = ["reference_fusion", "reference_object_heatmap", "run_map_benchmark"]


def reference_fusion(m: AVLMap, rgb, depth, K, T_world_cam, context) -> dict:
    """Per-point loop fusion of one frame into a dict {voxel index: [feature sum, count]}."""
    feats = m.dense.encode_dense(rgb, context)
    pts, px = frame_points(depth, K, T_world_cam, m.config.pixel_step)
    s = m.dense.stride
    acc: dict = {}
    g = m.grid
    for p, (r, c) in zip(pts, px, strict=True):
        idx = tuple(int(v) for v in np.floor((p - g.lower) / g.voxel_size))
        if not all(0 <= i < n for i, n in zip(idx, g.shape, strict=True)):
            continue
        f = feats[min(r // s, feats.shape[0] - 1), min(c // s, feats.shape[1] - 1)]
        if idx in acc:
            acc[idx][0] += f
            acc[idx][1] += 1
        else:
            acc[idx] = [f.astype(np.float64), 1]
    return acc


def _fusion_against_reference(m: AVLMap, recording, i: int) -> float:
    """The largest difference between the mean features of frame ``i`` fused as the map fuses
    (into an empty voxel map) and the per-point reference's (:func:`reference_fusion`)."""
    rgb, depth = recording.rgb[i], recording.depth[i]
    ctx = {"segmentation": recording.segmentation[i]}
    ref = reference_fusion(m, rgb, depth, recording.K, recording.T_world_cam[i], ctx)
    feats = m.dense.encode_dense(rgb, ctx)
    pts, px = frame_points(depth, recording.K, recording.T_world_cam[i], m.config.pixel_step)
    s = m.dense.stride
    h, w = feats.shape[:2]
    row = np.minimum(px[:, 0] // s, h - 1) * w + np.minimum(px[:, 1] // s, w - 1)
    v = VoxelMap(m.grid, m.voxels.dim)
    v.integrate(pts, feats.reshape(h * w, -1), rgb[px[:, 0], px[:, 1]], feature_index=row)
    if v.n != len(ref):
        return float("inf")
    want = [ref[tuple(int(c) for c in k)] for k in v.indices]
    want = np.stack([f_sum / count for f_sum, count in want])
    return float(np.abs(v.mean_features(normalize=False) - want).max())


def reference_object_heatmap(m: AVLMap, target_points: np.ndarray, decay: float) -> np.ndarray:
    """H = max(1 - decay * d_min, 0) by looping over target points (O(N*M))."""
    xs, ys, zs = m.grid.axes()
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    d = np.full(X.shape, np.inf)
    for p in target_points:
        d = np.minimum(d, np.sqrt((X - p[0]) ** 2 + (Y - p[1]) ** 2 + (Z - p[2]) ** 2))
    return np.maximum(1.0 - decay * d, 0.0).astype(np.float32)


def default_encoder_speed(recording, frames: int = 40) -> dict:
    """Frames/s of the embedded default image encoder (dense and global embeddings from one
    forward pass) on ``frames`` frames of ``recording``, its median ms per frame on one thread
    against the same network on torch and its int8 graph (``encoder_*_1thread``), and ms per
    1 s audio segment."""
    from tabletop.mapping.encoders.registry import make_encoders

    enc = make_encoders("default")
    idx = np.linspace(0, len(recording) - 1, frames).astype(int)
    enc.dense.encode_dense_and_global(recording.rgb[idx[0]])  # warm-up
    t0 = time.perf_counter()
    for i in idx:
        enc.dense.encode_dense_and_global(recording.rgb[i])
    fps = len(idx) / (time.perf_counter() - t0)
    # ms per 1 s of audio: the default audio encoder and the earlier log-mel network,
    # interleaved so that load affects both
    from tabletop.mapping.encoders.audio import MelCNNAudioEncoder

    old_audio = MelCNNAudioEncoder()
    seg = np.random.default_rng(0).normal(0, 0.1, 16000).astype(np.float32)
    enc.audio.encode_audio(seg, 16000)
    old_audio.encode_audio(seg, 16000)
    audio_s = old_audio_s = 0.0
    for _ in range(10):
        t0 = time.perf_counter()
        enc.audio.encode_audio(seg, 16000)
        t1 = time.perf_counter()
        old_audio.encode_audio(seg, 16000)
        audio_s, old_audio_s = audio_s + t1 - t0, old_audio_s + time.perf_counter() - t1
    audio_ms, old_audio_ms = audio_s * 100, old_audio_s * 100
    # Map build time per frame, the image encoder's share of it: the shipped default network
    # against the earlier small one, interleaved in the same run so that load affects both.
    from tabletop.mapping.encoders.lseg import VISION_WEIGHTS_PATH, LSegEncoder

    small = LSegEncoder(VISION_WEIGHTS_PATH)
    small.encode_dense_and_global(recording.rgb[idx[0]])
    t_new = t_old = 0.0
    for i in idx[: max(1, frames // 2)]:
        t0 = time.perf_counter()
        enc.dense.encode_dense_and_global(recording.rgb[i])
        t1 = time.perf_counter()
        small.encode_dense_and_global(recording.rgb[i])
        t_new, t_old = t_new + t1 - t0, t_old + time.perf_counter() - t1
    n = max(1, frames // 2)
    return {
        "encoder_fps": round(fps, 1),
        "encoder": enc.names["dense"],
        "encoder_ms_per_frame": round(t_new / n * 1000, 1),
        "small_encoder_ms_per_frame": round(t_old / n * 1000, 1),
        "encoder_vs_small_ratio": round(t_new / max(t_old, 1e-9), 2),
        **_one_thread_encoder_times(enc.dense, recording, idx),
        "audio_encoder": enc.names["audio"],
        "audio_encoder_ms_per_1s": round(audio_ms, 2),
        "audio_melcnn_ms_per_1s": round(old_audio_ms, 2),
    }


def _one_thread_encoder_times(image, recording, idx) -> dict:
    """Median ms per frame of the default image encoder (dense and global embeddings) on one
    thread, as it runs (onnxruntime where it can), of the same network on torch and of its
    opt-in int8 graph (``backend="int8"``; None where it cannot be built), the three
    alternating frame by frame so that load from other processes affects them alike."""
    from tabletop.mapping.encoders.lseg import LSegEncoder

    fast = LSegEncoder(image.weights, num_threads=1)
    ref = LSegEncoder(image.weights, num_threads=1, backend="torch")
    int8 = LSegEncoder(image.weights, num_threads=1, backend="int8")
    first = recording.rgb[idx[0]]
    runs = {"fast": fast, "ref": ref}
    if int8._session(first) is not fast._session(first):  # the int8 graph was built
        runs["int8"] = int8
    times = {k: [] for k in runs}
    for e in runs.values():  # warm-up (and, once per machine, the graphs' export)
        e.encode_dense_and_global(first)
    for i in idx:
        for k, e in runs.items():
            t0 = time.perf_counter()
            e.encode_dense_and_global(recording.rgb[i])
            times[k].append(time.perf_counter() - t0)
    t = {k: np.array(v) for k, v in times.items()}

    def ms(k):
        return round(float(np.median(t[k])) * 1000, 1) if k in t else None

    def ratio(k):
        return round(float(np.median(t[k] / t["ref"])), 2) if k in t else None

    return {
        "encoder_backend": "onnxruntime" if fast._session(first) is not None else "torch",
        "encoder_ms_per_frame_1thread": ms("fast"),
        "encoder_torch_ms_per_frame_1thread": ms("ref"),
        "encoder_vs_torch_ratio_1thread": ratio("fast"),
        "encoder_int8_ms_per_frame_1thread": ms("int8"),
        "encoder_int8_vs_torch_ratio_1thread": ratio("int8"),
    }


#: Sound queries and areas (regions of the table, as the reader reads "the left side of the
#: table", "the middle of the table", "the far right corner", "the far half") the benchmark
#: times; found or not, each is the map's whole answer.
BENCH_SOUNDS = ("a dog barking", "a bell ringing", "glass breaking", "a cat meowing")
BENCH_REGIONS = (("left", None), ("middle", "middle"), ("right", "far"), (None, "far"))


def _timed(call, inputs, repeat: int = 5) -> tuple[float, float]:
    """(median, p95) [ms] of ``call(x)`` over ``inputs``, each ``repeat`` times after one
    untimed call (caches warmed: the encoders' text embeddings, the instances)."""
    for x in inputs:
        call(x)
    times = []
    for _ in range(repeat):
        for x in inputs:
            t0 = time.perf_counter()
            call(x)
            times.append(time.perf_counter() - t0)
    ms = np.array(times) * 1000
    return round(float(np.median(ms)), 2), round(float(np.percentile(ms, 95)), 2)


def _modal_query_times(m: AVLMap, recording, image_frames: int = 6) -> dict:
    """Median and p95 of a sound, an area and an image query with its target (heatmap and
    argmax) on map ``m``; the image queries are frames of ``recording`` itself (the wrist
    camera's own views). The areas are regions as the reader gives them: reading words is the
    reader's own benchmark."""
    from tabletop.mapping.table_regions import AreaRef, TableRegion

    def answer(h):
        if h.found:
            m.get_max_pos_3d(h)

    areas = [
        AreaRef(f"{lat} {dep}", TableRegion(lat, dep, f"{lat} {dep}"), how="bench")
        for lat, dep in BENCH_REGIONS
    ]
    frames = np.linspace(0, len(recording) - 1, image_frames).astype(int)
    out = {}
    for name, call, inputs in (
        ("sound", lambda q: answer(m.sound_heatmap(q)), BENCH_SOUNDS),
        ("area", lambda a: answer(m.area_heatmap(a, major=True)), areas),
        ("image", lambda i: answer(m.image_heatmap(recording.rgb[i])), frames),
    ):
        med, p95 = _timed(call, inputs, repeat=2 if name == "image" else 5)
        out[f"{name}_query_ms"], out[f"{name}_query_ms_p95"] = med, p95
    return out


def run_map_benchmark(recording, reference_frames: int = 3, save_to=None) -> dict:
    """Build an oracle map of ``recording`` and time fusion and queries against references;
    the map is written to ``save_to`` when given (the viewer's benchmark opens it)."""
    m = AVLMap.build(recording, MapConfig(), encoders="oracle")
    if save_to is not None:
        m.save(save_to)
    st = m.stats
    fusion_fps = st.fused_frames / st.fusion_s
    encoder_fps = st.frames / st.encoder_s

    # Reference fusion on a few frames, timed without the encoder.
    idx = np.linspace(0, len(recording) - 1, reference_frames).astype(int)
    ref_s = 0.0
    for i in idx:
        ctx = {"segmentation": recording.segmentation[i]}
        t0 = time.perf_counter()
        reference_fusion(
            m, recording.rgb[i], recording.depth[i], recording.K, recording.T_world_cam[i], ctx
        )
        ref_s += time.perf_counter() - t0
    # the reference's time includes its encoder call: subtract ours, measured the same way
    enc_per_frame = st.encoder_s / st.frames
    ref_fps = reference_frames / max(ref_s - enc_per_frame * reference_frames, 1e-9)
    fusion_diff = _fusion_against_reference(m, recording, int(idx[-1]))

    labels = [o["label"] for o in recording.ground_truth["objects"]]
    m.text.encode_text(labels)  # text embeddings are cached; time the map's own work
    times = []
    for q in labels:
        t0 = time.perf_counter()
        h = m.object_heatmap(q)
        m.get_max_pos_3d(h)
        times.append(time.perf_counter() - t0)
    query_ms = float(np.median(times) * 1000)

    # Reference on one query; check it agrees with ours.
    q = labels[0]
    s, beats = m.object_scores(q)
    cand = np.nonzero(beats)[0]
    best = s[cand].max()
    keep = cand[s[cand] >= best - m.config.object.select_margin * (best - np.median(s))]
    pts = m.voxels.centers[keep]
    t0 = time.perf_counter()
    ref = reference_object_heatmap(m, pts, m.config.major_decay)
    ref_ms = (time.perf_counter() - t0) * 1000
    agree = float(np.abs(ref - m.object_heatmap(q).values).max())

    modal = _modal_query_times(m, recording)

    # Object instances: segmenting the whole map (done once per map change, then cached).
    from tabletop.mapping.instances import segment_instances

    t0 = time.perf_counter()
    n_inst = len(segment_instances(m.voxels, m.table()))
    segment_ms = (time.perf_counter() - t0) * 1000

    return {
        "map_frames": st.frames,
        "instances": n_inst,
        "instance_segmentation_ms": round(segment_ms, 1),
        "map_voxels": st.voxels,
        "encoders_for_map_bench": m.encoder_names.get("set", "oracle"),
        **default_encoder_speed(recording),
        "oracle_encoder_fps": round(encoder_fps, 1),
        "fusion_fps": round(fusion_fps, 1),
        "fusion_reference_fps": round(ref_fps, 2),
        "fusion_speedup": round(fusion_fps / ref_fps, 1),
        "fusion_reference_max_abs_diff": fusion_diff,
        "query_ms": round(query_ms, 2),
        "query_reference_ms": round(ref_ms, 1),
        "query_speedup": round(ref_ms / query_ms, 1),
        "query_reference_max_abs_diff": agree,
        **modal,
        "map_mb": round(m.voxels.nbytes / 1e6, 1),
        "heatmap_mb": round(np.zeros(m.grid.shape, np.float32).nbytes / 1e6, 2),
        "grid_shape": list(m.grid.shape),
    }
