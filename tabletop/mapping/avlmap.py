"""The AVLMap: a voxel map of vision-language features plus per-frame image embeddings, and
audio segments tied to the poses where they were heard; queries in any modality become heatmaps.

Build it from a recording with :meth:`AVLMap.build` (batch) or frame by frame with
:meth:`AVLMap.add_frame` and :meth:`AVLMap.add_audio` (online: the same result). Queries:
:meth:`object_heatmap` (text), :meth:`sound_heatmap` (text), :meth:`area_heatmap` (text),
:meth:`image_heatmap` (an RGB image of the table), each returning a :class:`Heatmap` with a
``confidence`` and ``found`` flag.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy import ndimage

from tabletop.errors import ConfigError
from tabletop.mapping.audio_segments import AudioSegment, NoiseGateConfig, segment_audio
from tabletop.mapping.calibration import load_calibration
from tabletop.mapping.encoders.base import check_same_space
from tabletop.mapping.grid import VoxelGrid
from tabletop.mapping.heatmaps import (
    AUX_DECAY,
    MAJOR_DECAY,
    point_heatmap_3d,
    scored_points_heatmap_xy,
)
from tabletop.mapping.visual_localization import (
    PhotometricCheck,
    VisualDatabase,
    VisualDatabaseError,
    VisualLocalization,
    VisualLocalizationConfig,
    check_rgb,
    localize_image,
)
from tabletop.mapping.voxel_map import VoxelMap, frame_points
from tabletop.sim.catalog import OBJECT_KINDS
from tabletop.transforms import pixel_rays

__all__ = ["DEFAULT_CATEGORIES", "OBJECT_CATEGORIES", "AVLMap", "Heatmap", "MapConfig", "MapStats"]

log = logging.getLogger(__name__)

_BACKGROUND = ("table", "floor", "robot arm", "other")
#: Object nouns of the default vocabulary: the simulator catalog's kinds.
OBJECT_CATEGORIES = tuple(k.label for k in OBJECT_KINDS.values())
#: The vocabulary a text query competes against: tabletop objects and the background.
DEFAULT_CATEGORIES = (*OBJECT_CATEGORIES, *_BACKGROUND)


@dataclass(frozen=True)
class MapConfig:
    """How a map is built and queried."""

    grid: VoxelGrid = field(default_factory=VoxelGrid)
    """The workspace box and voxel size (1 cm by default)."""
    pixel_step: int = 3
    """Fuse every ``pixel_step``-th pixel row and column. At 320x240 and the scans' 0.3-0.7 m
    range a pixel spans 1.4-3.3 mm, so every third pixel still samples each 1 cm voxel a
    camera sees several times; use 1 for 5 mm voxels or distant views."""
    frame_step: int = 1
    """Encode and fuse every ``frame_step``-th frame (voxels and area-module embeddings)."""
    categories: tuple[str, ...] = DEFAULT_CATEGORIES
    """Vocabulary a text query competes against (with "other")."""
    major_decay: float = MAJOR_DECAY
    """Decay [1/m] of primary heatmaps (``get_major_map``)."""
    aux_decay: float = AUX_DECAY
    """Decay [1/m] of auxiliary heatmaps (``get_map``)."""
    select_margin: float = 0.1
    """Target voxels score within this fraction of (best - median) of the best voxel."""
    min_confidence: float = 0.5
    """Below this calibrated confidence a query is reported as not found."""
    gate: NoiseGateConfig = field(default_factory=NoiseGateConfig)
    self_filter_margin: float | None = 0.01
    """Drop points within this margin [m] of the robot's links (None: keep them)."""
    visual: VisualLocalizationConfig | None = field(default_factory=VisualLocalizationConfig)
    """The visual localization module's reference frames and matcher (None: no image goals)."""
    image_target_px: float = 0.2
    """An image goal's target is the median surface point of the rays through the central
    ``image_target_px`` fraction of the image's width and height."""

    def __post_init__(self) -> None:
        if self.pixel_step < 1 or self.frame_step < 1:
            raise ConfigError("pixel_step and frame_step must be >= 1")
        if "other" not in self.categories:
            raise ConfigError("categories must include 'other'")
        if not 0 < self.image_target_px <= 1:
            raise ConfigError(f"image_target_px must be in (0, 1], got {self.image_target_px}")


@dataclass(frozen=True)
class Heatmap:
    """A query's heatmap over the map's grid, with what produced it."""

    values: np.ndarray  # grid.shape float32 in [0, 1]
    query: str
    modality: str  # "object" | "sound" | "area" | "image" | "fused"
    decay: float  # [1/m]
    confidence: float  # calibrated, in [0, 1]
    found: bool
    reason: str = ""
    target: np.ndarray | None = field(default=None, compare=False)
    """(3,) [m] world frame: the point the query names, for a module that locates one point
    (image: the surface point the image shows at its centre); else None."""
    evidence: float | None = None
    """The raw margin the confidence was computed from (see :mod:`tabletop.mapping.calibration`);
    None when nothing matched at all."""


@dataclass(frozen=True)
class MapStats:
    frames: int
    fused_frames: int
    encoder_s: float
    fusion_s: float
    voxels: int
    audio_segments: int
    reference_frames: int = 0  # frames kept by the visual localization module
    visual_s: float = 0.0  # time spent extracting their local features [s]


def _tcp_positions(T_world_hand: np.ndarray) -> np.ndarray:
    from tabletop.sim.scan import T_hand_tcp

    T = T_world_hand @ T_hand_tcp()
    return T[:, :3, 3]


def _look_at_table(T_world_cam: np.ndarray) -> np.ndarray:
    """(N, 2) xy where each camera's optical axis meets the table plane z = 0."""
    o = T_world_cam[:, :3, 3]
    d = T_world_cam[:, :3, 2]
    t = np.where(d[:, 2] < -1e-3, -o[:, 2] / np.minimum(d[:, 2], -1e-3), 0.5)
    return (o + t[:, None] * d)[:, :2]


class AVLMap:
    """The audio-visual-language map of one recording."""

    def __init__(
        self,
        config: MapConfig,
        text,
        dense,
        global_image,
        audio,
        encoder_names: dict[str, str] | None = None,
        encoder_set: str = "custom",
        rebuild_info: dict | None = None,
        audio_text=None,
    ) -> None:
        for enc in (dense, global_image):
            if enc is not None:
                check_same_space(text, enc)
        self.audio_text = audio_text if audio_text is not None else text
        """Text encoder of sound queries: ``text`` unless the audio encoder has its own space
        (CLAP)."""
        if audio is not None:
            check_same_space(self.audio_text, audio)
        self.calibration = load_calibration(encoder_set)
        """Confidence calibration of this encoder set (uncalibrated prior when none was fit)."""
        self.config = config
        self.grid = config.grid
        self.text, self.dense, self.global_image, self.audio_encoder = (
            text,
            dense,
            global_image,
            audio,
        )
        self.encoder_names = dict(encoder_names or {})
        self.encoder_set = encoder_set
        self.rebuild_info = dict(rebuild_info or {})
        self.voxels = VoxelMap(self.grid, text.dim)
        self.frame_embeddings: list[np.ndarray] = []
        self.frame_poses: list[np.ndarray] = []  # T_world_cam
        self.segments: list[AudioSegment] = []
        self.segment_embeddings: list[np.ndarray] = []
        self.segment_positions: list[np.ndarray] = []  # (3,) mean TCP while heard
        self.visual = None if config.visual is None else VisualDatabase(config.visual)
        """The visual localization module's reference frames (None: no image goals)."""
        self._frames_seen = 0
        self._check: tuple[int, PhotometricCheck] | None = None  # (frames seen, check)
        self.encoder_s = 0.0
        self.fusion_s = 0.0
        self.visual_s = 0.0

    # ------------------------------------------------------------------ building
    def add_frame(
        self,
        rgb,
        depth,
        K,
        T_world_cam,
        context: dict | None = None,
        joint_positions: np.ndarray | None = None,
    ) -> None:
        """Fuse one RGB-D frame (online). ``context`` feeds the encoders (oracle: segmentation);
        with ``joint_positions`` the robot's own points are filtered out. Every
        ``config.visual.stride``-th frame is kept as a visual reference frame."""
        i = self._frames_seen
        self._frames_seen += 1
        if self.visual is not None:
            t = time.perf_counter()
            self.visual.add_frame(rgb, depth, K, T_world_cam)
            self.visual_s += time.perf_counter() - t
        t0 = time.perf_counter()
        fuse_frame = i % self.config.frame_step == 0
        feats = None
        if self.global_image is not None and fuse_frame:  # the area module: fused frames
            both = getattr(self.dense, "encode_dense_and_global", None)
            if self.global_image is self.dense and both is not None:
                feats, g = both(rgb)  # one network gives both: one forward pass
            else:
                g = self.global_image.encode_image(rgb, context)
            self.frame_embeddings.append(g)
            self.frame_poses.append(np.asarray(T_world_cam, np.float64))
        if not fuse_frame:
            self.encoder_s += time.perf_counter() - t0
            return
        if feats is None:
            feats = self.dense.encode_dense(rgb, context)
        t1 = time.perf_counter()
        pts, px = frame_points(depth, K, T_world_cam, self.config.pixel_step)
        if joint_positions is not None and self.config.self_filter_margin is not None:
            if getattr(self, "_self_filter", None) is None:
                from tabletop.mapping.self_filter import RobotSelfFilter

                self._self_filter = RobotSelfFilter(self.config.self_filter_margin)
            keep = ~self._self_filter.mask(pts, joint_positions)
            pts, px = pts[keep], px[keep]
        s = self.dense.stride
        cell = feats[
            np.minimum(px[:, 0] // s, feats.shape[0] - 1),
            np.minimum(px[:, 1] // s, feats.shape[1] - 1),
        ]
        self.voxels.integrate(pts, cell, rgb[px[:, 0], px[:, 1]])
        t2 = time.perf_counter()
        self.encoder_s += t1 - t0
        self.fusion_s += t2 - t1

    def add_audio(
        self, audio: np.ndarray, sample_rate: int, timestamps: np.ndarray, T_world_hand: np.ndarray
    ) -> None:
        """Segment a recording's audio track and tie each segment to the poses heard from."""
        segs = segment_audio(audio, sample_rate, self.config.gate)
        tcp = _tcp_positions(np.asarray(T_world_hand))
        for seg in segs:
            heard = (timestamps >= seg.start_s) & (timestamps <= seg.end_s)
            if not heard.any():
                heard = np.abs(timestamps - (seg.start_s + seg.end_s) / 2) == np.min(
                    np.abs(timestamps - (seg.start_s + seg.end_s) / 2)
                )
            a, b = int(seg.start_s * sample_rate), int(seg.end_s * sample_rate)
            emb = self.audio_encoder.encode_audio(
                audio[a:b], sample_rate, {"span_s": (seg.start_s, seg.end_s)}
            )
            self.segments.append(seg)
            self.segment_embeddings.append(emb)
            self.segment_positions.append(tcp[heard].mean(axis=0))

    @classmethod
    def build(
        cls,
        recording,
        config: MapConfig | None = None,
        encoders: str = "oracle",
        progress: Callable[[int, int], None] | None = None,
        encoder_options: dict | None = None,
    ) -> AVLMap:
        """Build a map from a whole recording with the named encoder set (``encoder_options``:
        see :func:`~tabletop.mapping.encoders.registry.make_encoders`)."""
        from tabletop.mapping.encoders.registry import make_encoders

        config = config or MapConfig()
        enc = make_encoders(encoders, recording, encoder_options)
        m = cls(
            config,
            enc.text,
            enc.dense,
            enc.global_image,
            enc.audio,
            enc.names,
            encoders,
            enc.rebuild,
            enc.audio_text,
        )
        T_cam = recording.T_world_cam
        for i in range(len(recording)):
            ctx = None
            if recording.segmentation is not None:
                ctx = {"segmentation": recording.segmentation[i]}
            m.add_frame(
                recording.rgb[i],
                recording.depth[i],
                recording.K,
                T_cam[i],
                ctx,
                recording.joint_positions[i],
            )
            if progress is not None:
                progress(i + 1, len(recording))
        if recording.audio is not None and m.audio_encoder is not None:
            m.add_audio(
                recording.audio, recording.audio_rate, recording.timestamps, recording.T_world_hand
            )
        return m

    def save(self, path) -> Path:
        """Write the map to ``path`` (.npz); see :mod:`tabletop.mapping.persistence`."""
        from tabletop.mapping.persistence import save_map

        return save_map(self, path)

    @classmethod
    def load(cls, path) -> AVLMap:
        """Load a map saved by :meth:`save`, re-creating its encoder set."""
        from tabletop.mapping.encoders.registry import make_encoders_from_rebuild
        from tabletop.mapping.persistence import MapFormatError, read_map_file

        h, a = read_map_file(path)
        c = h["config"]
        try:
            config = MapConfig(
                grid=VoxelGrid(
                    tuple(c["grid"]["lower"]), tuple(c["grid"]["upper"]), c["grid"]["voxel_size"]
                ),
                pixel_step=c["pixel_step"],
                frame_step=c["frame_step"],
                categories=tuple(c["categories"]),
                major_decay=c["major_decay"],
                aux_decay=c["aux_decay"],
                select_margin=c["select_margin"],
                min_confidence=c["min_confidence"],
                gate=NoiseGateConfig(**c["gate"]),
                self_filter_margin=c["self_filter_margin"],
                visual=None,  # restored with the reference frames below
            )
        except (KeyError, TypeError, ConfigError) as e:
            raise MapFormatError(f"{path}: config is invalid: {e}") from None
        enc = make_encoders_from_rebuild(h["encoder_set"], h["rebuild"])
        if enc.text.space != h["space"] or enc.text.dim != h["dim"]:
            raise MapFormatError(
                f"{path}: built in space {h['space']!r} ({h['dim']}-d), but its encoders now "
                f"give {enc.text.space!r} ({enc.text.dim}-d)"
            )
        m = cls(
            config,
            enc.text,
            enc.dense,
            enc.global_image,
            enc.audio,
            h["encoders"],
            h["encoder_set"],
            h["rebuild"],
            enc.audio_text,
        )
        try:
            m.voxels = VoxelMap.from_state(
                config.grid,
                h["dim"],
                {
                    "linear": a["voxel_linear"],
                    "feature_sums": a["voxel_feature_sums"],
                    "counts": a["voxel_counts"],
                    "color_sums": a["voxel_color_sums"],
                },
            )
        except ConfigError as e:
            raise MapFormatError(f"{path}: {e}") from None
        m.frame_embeddings = list(a["frame_embeddings"])
        m.frame_poses = list(a["frame_poses"])
        m.segments = [AudioSegment(float(s0), float(s1)) for s0, s1 in h["segments"]]
        m.segment_embeddings = list(a["segment_embeddings"])
        m.segment_positions = list(a["segment_positions"])
        m._frames_seen = int(h["frames_seen"])
        if h.get("visual") is not None:
            visual = {k.removeprefix("visual_"): v for k, v in a.items() if k.startswith("visual_")}
            try:
                m.visual = VisualDatabase.from_state(h["visual"], visual)
            except VisualDatabaseError as e:
                raise VisualDatabaseError(f"{path}: {e}") from None
            m.config = replace(config, visual=m.visual.config)
        return m

    @property
    def stats(self) -> MapStats:
        fused = (self._frames_seen + self.config.frame_step - 1) // self.config.frame_step
        return MapStats(
            self._frames_seen,
            fused,
            self.encoder_s,
            self.fusion_s,
            self.voxels.n,
            len(self.segments),
            0 if self.visual is None else len(self.visual),
            self.visual_s,
        )

    # ------------------------------------------------------------------ queries
    def _decay(self, major: bool) -> float:
        return self.config.major_decay if major else self.config.aux_decay

    def _features(self) -> np.ndarray:
        """Normalised mean voxel features, cached until the map changes."""
        key = (self.voxels.n, self._frames_seen)
        if getattr(self, "_feat_key", None) != key:
            self._feat_cache = self.voxels.mean_features()
            self._feat_key = key
        return self._feat_cache

    def _background_scores(self) -> np.ndarray:
        """Per voxel, the best score of the background concepts (cached with the features)."""
        f = self._features()
        if getattr(self, "_bg_key", None) != self._feat_key:
            bg = self.text.encode_text(list(_BACKGROUND))
            self._bg_cache = (f @ bg.T).max(axis=1)
            self._bg_key = self._feat_key
        return self._bg_cache

    def object_scores(self, query: str) -> tuple[np.ndarray, np.ndarray]:
        """Per occupied voxel: the query's cosine score, and whether the query beats the
        background concepts there."""
        s = self._features() @ self.text.encode_text([query])[0]
        return s, s > self._background_scores()

    def object_heatmap(self, query: str, major: bool = True) -> Heatmap:
        """Heat around the voxels that best match ``query`` (the object module)."""
        decay = self._decay(major)
        if self.voxels.n == 0:
            return self._empty(query, "object", decay, "the map is empty")
        s, beats = self.object_scores(query)
        cand = np.nonzero(beats)[0]
        if not len(cand):
            return self._empty(
                query, "object", decay, f"no voxel matches {query!r} better than the background"
            )
        best = s[cand].max()
        floor = np.median(s)
        keep = cand[s[cand] >= best - self.config.select_margin * (best - floor)]
        mask = np.zeros(self.grid.size, bool)
        mask[self.voxels.linear_indices[keep]] = True
        values = point_heatmap_3d(self.grid, mask.reshape(self.grid.shape), decay)
        conf = self._confidence("object", best - floor)
        found = self._found("object", best - floor, conf)
        return Heatmap(
            values,
            query,
            "object",
            decay,
            conf,
            found,
            "" if found else f"best match {best:.2f} is weak (confidence {conf:.2f})",
            evidence=float(best - floor),
        )

    def _empty(self, query: str, modality: str, decay: float, reason: str) -> Heatmap:
        """A not-found result: an all-zero heatmap with the reason."""
        return Heatmap(
            np.zeros(self.grid.shape, np.float32), query, modality, decay, 0.0, False, reason
        )

    def _confidence(self, modality: str, margin: float) -> float:
        """Calibrated confidence in [0, 1] of a query whose best score beats the map's typical
        score by ``margin`` (:mod:`tabletop.mapping.calibration`)."""
        return self.calibration.confidence(modality, float(margin))

    def _found(self, modality: str, margin: float, confidence: float) -> bool:
        """The calibration's operating point, else ``confidence >= config.min_confidence``."""
        return self.calibration.found(modality, margin, confidence, self.config.min_confidence)

    def _scores(
        self, embeddings: list[np.ndarray], query: str, text=None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Cosine scores of stored embeddings with ``query``, raw and min-max normalised."""
        s = np.stack(embeddings) @ (text or self.text).encode_text([query])[0]
        return s, _normalize_scores(s)

    def sound_heatmap(self, query: str, major: bool = True) -> Heatmap:
        """Heat around where the sound best matching ``query`` was heard (the audio module)."""
        decay = self._decay(major)
        if not self.segment_embeddings:
            return self._empty(query, "sound", decay, "the map has no audio segments")
        s, scores = self._scores(self.segment_embeddings, query, self.audio_text)
        pos = np.stack(self.segment_positions)[:, :2]
        values = scored_points_heatmap_xy(self.grid, pos, scores, decay)
        floor = float(np.median(s)) if len(s) > 2 else float(s.min(initial=0.0))
        conf = self._confidence("sound", float(s.max()) - floor)
        # a median of one or two scores says nothing about the typical score: not judged
        found = self._found("sound", float(s.max()) - floor, conf) or len(s) <= 2
        return Heatmap(
            values,
            query,
            "sound",
            decay,
            conf,
            found,
            "" if found else "no sound segment matches well",
            evidence=float(s.max()) - floor,
        )

    def area_heatmap(self, query: str, major: bool = False) -> Heatmap:
        """Heat where frames whose global embedding matches ``query`` looked (the area module)."""
        decay = self._decay(major)
        if not self.frame_embeddings:
            return self._empty(query, "area", decay, "the map has no frame embeddings")
        s, scores = self._scores(self.frame_embeddings, query)
        pts = _look_at_table(np.stack(self.frame_poses))
        top = scores >= 0.8  # the best-matching views carry the area
        values = scored_points_heatmap_xy(self.grid, pts[top], scores[top], decay)
        margin = float(s.max()) - float(np.median(s))
        conf = self._confidence("area", margin)
        return Heatmap(values, query, "area", decay, conf, True, evidence=margin)

    def localize(self, rgb: np.ndarray, K: np.ndarray | None = None) -> VisualLocalization:
        """Where the camera was when it took ``rgb`` (H, W, 3) uint8 (the visual localization
        module); ``ok=False`` with a reason when that is not known. ``K`` (3, 3) [px] is needed
        for an image of another size than the map's reference frames (another camera)."""
        rgb = check_rgb(rgb)
        if self.visual is None:
            return VisualLocalization(
                False,
                "the map has no visual localization module (MapConfig.visual=None)",
                None,
                None,
            )
        size = (rgb.shape[1], rgb.shape[0])
        if K is None and len(self.visual) and size != self.visual.image_size:
            raise ConfigError(
                f"the image is {size[0]}x{size[1]} px but the map's camera "
                f"{self.visual.image_size[0]}x{self.visual.image_size[1]}: pass its intrinsics K"
            )
        return localize_image(self.visual, rgb, K, check=self.photometric_check())

    def photometric_check(self) -> PhotometricCheck:
        """The map's voxel colours as a :class:`PhotometricCheck` of candidate camera poses
        (built on first use, again after frames were added)."""
        if self._check is None or self._check[0] != self._frames_seen:
            check = PhotometricCheck(self.grid, self.voxels.indices, self.voxels.mean_colors())
            self._check = (self._frames_seen, check)
        return self._check[1]

    def image_target(
        self, T_world_cam: np.ndarray, K: np.ndarray, image_size: tuple[int, int]
    ) -> np.ndarray:
        """(3,) [m] world point an image taken from ``T_world_cam`` shows at its centre.

        Rays through a 5 x 5 grid over the central ``config.image_target_px`` of the image
        (``K`` (3, 3) [px], ``image_size`` = (width, height) [px]) are marched
        through the map's occupancy to the first occupied voxel, or to the table plane z = 0;
        the target is their per-axis median. A median of several rays is not swayed by one ray
        that grazes an object's edge.
        """
        w, h = image_size
        f = self.config.image_target_px / 2
        u, v = np.meshgrid(
            np.linspace(0.5 - f, 0.5 + f, 5) * w, np.linspace(0.5 - f, 0.5 + f, 5) * h
        )
        rays = pixel_rays(K, T_world_cam, u, v)
        c = np.asarray(T_world_cam, np.float64)[:3, 3]
        # March to the table plane (2 m at most).
        s_max = np.where(rays[:, 2] < -1e-6, -c[2] / np.minimum(rays[:, 2], -1e-6), 2.0)
        hit, first = self.grid.march(c, rays, self.voxels.occupancy(), np.minimum(s_max, 2.0))
        table = ~hit & (s_max < 2.0)
        hits = np.concatenate([first[hit], c + s_max[table, None] * rays[table]])
        if not len(hits):
            return c + s_max[len(rays) // 2] * rays[len(rays) // 2]
        return np.median(hits, axis=0)

    def image_heatmap(
        self, rgb: np.ndarray, major: bool = True, K: np.ndarray | None = None
    ) -> Heatmap:
        """Heat around the table region an image shows (the visual localization module).

        ``rgb`` (H, W, 3) uint8 is an image of the table, as the wrist camera would take it.
        The image is localised against the map's reference frames; its target ``p_v`` is the
        surface point at the image's centre (:meth:`image_target`), and
        ``H_v(p) = max(1 - eps * d_xy(p, p_v), 0)``. A failed localisation gives ``found=False``
        with its reason; malformed input raises :class:`ConfigError`. ``K``: see
        :meth:`localize`. ``evidence`` is the pose's photometric agreement beyond chance
        (kappa; of the refused best pose when not found, None when PnP gave no pose);
        ``confidence`` its calibration (:mod:`tabletop.mapping.calibration`), 0 when not found.
        """
        decay = self._decay(major)
        rgb = check_rgb(rgb)
        query = f"image {rgb.shape[1]}x{rgb.shape[0]}"
        loc = self.localize(rgb, K)
        if not loc.ok:
            return replace(self._empty(query, "image", decay, loc.reason), evidence=loc.kappa)
        conf = self._confidence("image", loc.kappa)
        K = self.visual.K if K is None else K
        target = self.image_target(loc.T_world_cam, K, (rgb.shape[1], rgb.shape[0]))
        values = scored_points_heatmap_xy(self.grid, target[None, :2], [1.0], decay)
        return Heatmap(values, query, "image", decay, conf, True, target=target, evidence=loc.kappa)

    def surface_z(self, xy: np.ndarray) -> float:
        """Height [m] of the top occupied voxel at ``xy`` (0, the table, where none)."""
        idx, inside = self.grid.world_to_index(np.array([[xy[0], xy[1], 0.0]]))
        if not inside[0]:
            return 0.0
        occ = self.voxels.occupancy()[idx[0, 0], idx[0, 1]]
        ks = np.nonzero(occ)[0]
        if not len(ks):
            return 0.0
        return float(self.grid.axes()[2][ks.max()] + self.grid.voxel_size / 2)

    def get_max_pos_3d(self, heatmap: Heatmap | np.ndarray) -> np.ndarray:
        """World point [m] of the heatmap's maximum.

        Ties (plateaus) resolve to the centroid of the largest connected tied region; when that
        region spans the whole height (a top-down heatmap), the point is placed on the surface
        beneath (the top of the map at that x, y).
        """
        values = heatmap.values if isinstance(heatmap, Heatmap) else np.asarray(heatmap)
        if values.shape != self.grid.shape:
            raise ConfigError(f"heatmap {values.shape} is not on this map's grid {self.grid.shape}")
        m = float(values.max())
        tied = values >= m - 1e-6
        labels, n = ndimage.label(tied, structure=np.ones((3, 3, 3)))
        if n > 1:
            weights = ndimage.sum(values, labels, index=np.arange(1, n + 1))
            tied = labels == (int(np.argmax(weights)) + 1)
        idx = np.argwhere(tied)
        p = self.grid.centers(idx).mean(axis=0)
        if len(np.unique(idx[:, 2])) == self.grid.shape[2]:
            p[2] = self.surface_z(p[:2])
        return p


def _normalize_scores(s: np.ndarray) -> np.ndarray:
    lo, hi = float(s.min()), float(s.max())
    if hi - lo < 1e-9:
        return np.ones_like(s, dtype=np.float64)
    return (s - lo) / (hi - lo)
