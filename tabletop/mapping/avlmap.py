"""The AVLMap: a voxel map of vision-language features plus per-frame image embeddings, audio
segments tied to the poses where they were heard, and reference frames for visual
localization; queries in any modality become :class:`~tabletop.mapping.heatmaps.Heatmap` values.

The map is a thin facade over the paper's four modules, each in its own file:
:class:`~tabletop.mapping.object_module.ObjectModule` (text against fused voxel features),
:class:`~tabletop.mapping.area_module.AreaModule` (text against per-frame embeddings),
:class:`~tabletop.mapping.audio_module.AudioModule` (text against sound segments) and
:class:`~tabletop.mapping.visual.module.VisualModule` (an image localised against reference
frames). Targets come from :mod:`tabletop.mapping.targets`.

Build it from a recording with :meth:`AVLMap.build` (batch) or frame by frame with
:meth:`AVLMap.add_frame` and :meth:`AVLMap.add_audio` (online: the same result). The map needs
nothing from the simulator: what it uses of a scan (intrinsics, camera and microphone poses,
joint positions for an optional robot self-filter) is in the recording. Its confidence
calibration is given to it (:class:`~tabletop.mapping.calibration.Calibration`; the
uncalibrated prior when none is), saved with it and restored on load.
"""

from __future__ import annotations

import logging
import os
import re
import time
import unicodedata
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from types import MappingProxyType
from typing import Protocol

import numpy as np

from tabletop.errors import ConfigError, RecordingError, TabletopError, check_bool
from tabletop.mapping.area_module import AreaModule
from tabletop.mapping.audio_module import AudioModule
from tabletop.mapping.audio_segments import AudioSegment
from tabletop.mapping.calibration import Calibration
from tabletop.mapping.config import MapConfig
from tabletop.mapping.encoders.base import check_same_space
from tabletop.mapping.encoders.minilm import MINILM_SPACE
from tabletop.mapping.errors import MapFormatError
from tabletop.mapping.heatmaps import Heatmap
from tabletop.mapping.object_module import ObjectModule
from tabletop.mapping.persistence import read_map_file, save_map, source_of
from tabletop.mapping.registration import table_corrections
from tabletop.mapping.table_regions import (
    AreaRef,
    TableFit,
    fit_surfaces,
    fit_table,
    raised_surfaces,
    region_heatmap,
)
from tabletop.mapping.targets import max_position
from tabletop.mapping.visual.database import VisualDatabase, VisualDatabaseError
from tabletop.mapping.visual.localization import VisualLocalization
from tabletop.mapping.visual.module import VisualModule, VisualModuleConfig
from tabletop.mapping.visual.photometric import PhotometricCheck
from tabletop.mapping.voxel_map import VoxelMap, frame_points
from tabletop.reader.lexicon.colour_words import FILLER_WORDS
from tabletop.reader.lexicon.words import negations, ordinal, relation_words
from tabletop.recording import Recording, load_recording

__all__ = ["QUERY_KINDS", "AVLMap", "MapStats", "SelfFilter"]

#: Query kinds (the robot API's keywords) -> the map's query method each names.
QUERY_KINDS = MappingProxyType(
    {
        "obj": "object_heatmap",
        "sound": "sound_heatmap",
        "area": "area_heatmap",
        "img": "image_heatmap",
    }
)

log = logging.getLogger(__name__)


class SelfFilter(Protocol):
    """Says which points of a frame lie on the robot (e.g.
    :class:`tabletop.arm.RobotSelfFilter`): ``mask(points_world (P, 3) [m], q (7,) [rad])``
    -> (P,) bool."""

    def mask(
        self, points_world: np.ndarray, q: np.ndarray, T_world_hand: np.ndarray | None = None
    ) -> np.ndarray: ...


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


class AVLMap:
    """The audio-visual-language map of one recording.

    Args:
        config: how the map is built and queried.
        text, dense, global_image, audio: the encoders (``global_image`` and ``audio`` may be
            None: no area or audio module).
        encoder_names, encoder_set, rebuild_info: what the encoders are, for reports and for
            re-creating them on load.
        audio_text: the text encoder of sound queries, when the audio encoder has its own
            space (CLAP); ``text`` otherwise.
        calibration: the confidence calibration of this encoder set (None: the uncalibrated
            prior).
        self_filter: drops the robot's own points from frames given with joint positions (None:
            no filtering).
    """

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
        *,
        calibration: Calibration | None = None,
        self_filter: SelfFilter | None = None,
    ) -> None:
        for enc in (dense, global_image):
            if enc is not None:
                check_same_space(text, enc)
        self.audio_text = audio_text if audio_text is not None else text
        """Text encoder of sound queries: ``text`` unless the audio encoder has its own space
        (CLAP)."""
        if audio is not None:
            check_same_space(self.audio_text, audio)
        if calibration is not None and not isinstance(calibration, Calibration):
            raise ConfigError(
                f"calibration must be a Calibration, got {type(calibration).__name__}"
            )
        self.calibration = calibration or Calibration(encoder_set, {}, {})
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
        self.source: dict = {}
        """What the map was built from (:func:`~tabletop.mapping.persistence.source_of`: the
        scene's name and fingerprint, the recording's fingerprint); empty when unknown."""
        self.self_filter = self_filter
        self.registration = None
        """The table registration :meth:`build` applied (a :class:`TableCorrections`; None for
        a map built frame by frame or loaded)."""
        self.voxels = VoxelMap(self.grid, text.dim)
        self.objects = ObjectModule(
            self.voxels, text, config.object, config.objects, config.descriptions, self.supports
        )
        """The object module."""
        self.areas = AreaModule(self.grid, config.area)
        """The area module (per-frame global embeddings and camera poses)."""
        self.sounds = AudioModule(self.grid, config.audio, getattr(audio, "vocabulary", None))
        """The audio module (segments, embeddings, where each was heard)."""
        visual = config.visual
        db = None if visual is None else VisualDatabase(visual.localization)
        self.images = VisualModule(
            self.voxels,
            db,
            0.2 if visual is None else visual.target_px,
            "view" if visual is None else visual.target,
        )
        """The visual localization module (its ``database`` is None: no image goals)."""
        self._table: tuple[tuple[int, int], TableFit | None] | None = None
        self._surfaces: tuple[tuple[int, int], list[TableFit]] | None = None
        self.lacks: tuple[str, ...] = ()
        """What a map loaded from an older file format lacks (empty for a new map)."""
        self._frames_seen = 0
        self.encoder_s = 0.0
        self.fusion_s = 0.0
        self.visual_s = 0.0

    @property
    def visual(self) -> VisualDatabase | None:
        """The visual localization module's reference frames (None: no image goals)."""
        return self.images.database

    @property
    def frames_seen(self) -> int:
        """Frames given to :meth:`add_frame` so far."""
        return self._frames_seen

    # ------------------------------------------------------------------ building
    def add_frame(
        self,
        rgb,
        depth,
        K,
        T_world_cam,
        context: dict | None = None,
        joint_positions: np.ndarray | None = None,
        T_world_hand: np.ndarray | None = None,
    ) -> None:
        """Fuse one RGB-D frame (online). ``context`` feeds the encoders (oracle: segmentation);
        with ``joint_positions`` and a self-filter the robot's own points are dropped (placed
        relative to ``T_world_hand``, the hand pose ``T_world_cam`` came from, when given).
        Every ``config.visual.localization.stride``-th frame is kept as a visual reference
        frame."""
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
            self.areas.add(g, T_world_cam)
        if not fuse_frame:
            self.encoder_s += time.perf_counter() - t0
            return
        # an encoder that can give the fused pixels' features alone does (the oracle's)
        at = getattr(self.dense, "encode_dense_at", None) if feats is None else None
        if feats is None and at is None:
            feats = self.dense.encode_dense(rgb, context)
        t1 = time.perf_counter()
        pts, px = frame_points(depth, K, T_world_cam, self.config.pixel_step)
        if (
            joint_positions is not None
            and self.self_filter is not None
            and self.config.self_filter_margin is not None
        ):
            keep = ~self.self_filter.mask(pts, joint_positions, T_world_hand)
            pts, px = pts[keep], px[keep]
        # the features as a table and each point's row in it: never a feature row per point
        if at is not None:
            t = time.perf_counter()
            table, row = at(rgb, context, px)
            t1 += time.perf_counter() - t  # encoder time, not fusion time
        else:
            s = self.dense.stride
            h, w = feats.shape[:2]
            table = feats.reshape(h * w, -1)
            row = np.minimum(px[:, 0] // s, h - 1) * w + np.minimum(px[:, 1] // s, w - 1)
        self.voxels.integrate(pts, table, rgb[px[:, 0], px[:, 1]], feature_index=row)
        t2 = time.perf_counter()
        self.encoder_s += t1 - t0
        self.fusion_s += t2 - t1

    def add_audio(
        self, audio: np.ndarray, sample_rate: int, timestamps: np.ndarray, T_world_mic: np.ndarray
    ) -> None:
        """Segment an audio track and tie each segment to the microphone poses (N, 4, 4) of the
        frames at ``timestamps`` (N,) [s] heard during it."""
        if self.audio_encoder is None:
            raise ConfigError("this map has no audio encoder: it cannot hold sounds")
        self.sounds.add(audio, sample_rate, timestamps, T_world_mic, self.audio_encoder)

    @classmethod
    def empty(
        cls,
        recording,
        config: MapConfig | None = None,
        encoders: str = "oracle",
        encoder_options: dict | None = None,
        calibration: Calibration | None = None,
        self_filter: SelfFilter | None = None,
    ) -> AVLMap:
        """A map with no frame yet, for ``recording``'s frames to be added one by one
        (:meth:`add_frame`, as :mod:`tabletop.mapping.online` does), with the encoder set
        ``encoders`` (see :meth:`build` for the rest)."""
        from tabletop.mapping.encoders.registry import make_encoders

        recording = _as_recording(recording)
        config = config or MapConfig()
        if encoders == "default":  # the config's image network and scale, unless told others
            chosen = {"vision_upscale": config.image_scale, "vision_network": config.image_network}
            encoder_options = {**chosen, **(encoder_options or {})}
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
            calibration=calibration,
            self_filter=self_filter,
        )
        m.source = source_of(recording)
        return m

    @classmethod
    def build(
        cls,
        recording,
        config: MapConfig | None = None,
        encoders: str = "oracle",
        progress: Callable[[int, int], None] | None = None,
        encoder_options: dict | None = None,
        *,
        calibration: Calibration | None = None,
        self_filter: SelfFilter | None = None,
    ) -> AVLMap:
        """Build a map from a whole recording with the named encoder set (``encoder_options``:
        see :func:`~tabletop.mapping.encoders.registry.make_encoders`). ``calibration``: the
        encoder set's confidence calibration (``load_calibration(encoders)``), ``self_filter``:
        see the class; ``progress(done, total)`` is called after each frame. ``recording``: a
        :class:`~tabletop.recording.Recording`, or the path of a recording on disk."""

        recording = _as_recording(recording)
        config = config or MapConfig()
        m = cls.empty(recording, config, encoders, encoder_options, calibration, self_filter)
        T_hand = recording.T_world_hand
        m.registration = table_corrections(
            recording.depth, recording.K, recording.T_world_cam, config.registration
        )
        if m.registration.any:  # the recorded poses, corrected onto the table
            T_hand = m.registration.C @ T_hand
        for i in range(len(recording)):
            m.add_recorded_frame(recording, i, T_hand[i])
            if progress is not None:
                progress(i + 1, len(recording))
        if len(recording) and m.voxels.n == 0:
            lo, hi = list(m.grid.lower), list(m.grid.upper)
            raise RecordingError(
                f"no depth point of the recording's {len(recording)} frames fell inside the "
                f"map's grid ({lo} .. {hi} m in the base frame): check that the poses are in "
                "metres in the robot's base frame and that the depth is valid"
            )
        m.add_recorded_audio(recording, T_hand)
        return m

    def add_recorded_frame(self, recording, i: int, T_world_hand: np.ndarray) -> None:
        """Fuse frame ``i`` of ``recording`` (:meth:`add_frame`) taken from the hand pose
        ``T_world_hand`` (the recorded one, or one corrected onto the table), with its
        segmentation as the encoders' context where the recording has one."""
        ctx = None
        if recording.segmentation is not None:
            ctx = {"segmentation": recording.segmentation[i]}
        self.add_frame(
            recording.rgb[i],
            recording.depth[i],
            recording.K,
            T_world_hand @ recording.T_hand_cam,
            ctx,
            recording.joint_positions[i],
            T_world_hand,
        )

    def add_recorded_audio(self, recording, T_world_hand: np.ndarray) -> None:
        """Segment ``recording``'s audio track (:meth:`add_audio`), heard from the microphone
        on the hand poses ``T_world_hand`` (N, 4, 4); nothing where it has no track or the map
        no audio encoder."""
        if recording.audio is not None and self.audio_encoder is not None:
            T_mic = T_world_hand @ recording.T_hand_mic
            self.add_audio(recording.audio, recording.audio_rate, recording.timestamps, T_mic)

    def save(self, path) -> Path:
        """Write the map to ``path`` (.npz); see :mod:`tabletop.mapping.persistence`."""
        return save_map(self, path)

    @classmethod
    def load(
        cls, path, *, calibration: Calibration | None = None, encoders: str | None = None
    ) -> AVLMap:
        """Load a map saved by :meth:`save`, re-creating its encoder set (file format:
        :mod:`tabletop.mapping.persistence`). ``calibration`` replaces the calibration saved with
        the map (a map of format 1-2 saved none: it gets the uncalibrated prior unless one is
        given). ``encoders``: the encoder set the caller expects; a map built with another
        raises :class:`MapFormatError` naming both. What an older file lacks is listed in
        :attr:`lacks`."""
        from tabletop.mapping.encoders.registry import make_encoders_from_rebuild

        h, a = read_map_file(path)
        if encoders is not None and h.get("encoder_set") != encoders:
            raise MapFormatError(
                f"{path} was built with the encoder set {h.get('encoder_set')!r}, not {encoders!r}"
            )
        lacks: list[str] = []
        try:
            c = dict(h["config"])
            saved_visual = c.pop("visual", None) or {}
            target_px = float(saved_visual.get("target_px", VisualModuleConfig().target_px))
            # what an image goal names ("view" or "camera": a room's base goes where the picture
            # was taken); files that predate it named the view
            target = str(saved_visual.get("target", VisualModuleConfig().target))
            if h["version"] < 3:
                lacks.append("its image target's size and the area module's config (defaults)")
            config = MapConfig.from_dict({**c, "visual": None})  # visual: with its frames below
        except (KeyError, TypeError, AttributeError, ValueError) as e:  # ConfigError included
            raise MapFormatError(f"{path}: config is invalid: {e}") from None
        if calibration is None:
            if h.get("calibration") is not None:
                try:
                    calibration = Calibration.from_json(h["calibration"], f"{path}: calibration")
                except TabletopError as e:
                    raise MapFormatError(str(e)) from None
            else:
                lacks.append("a saved calibration (the uncalibrated prior is used)")
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
            calibration=calibration,
        )
        try:
            m.voxels.restore(
                {
                    "linear": a["voxel_linear"],
                    "feature_sums": a["voxel_feature_sums"],
                    "counts": a["voxel_counts"],
                    "color_sums": a["voxel_color_sums"],
                    **({"height_sums": a["voxel_height_sums"]} if "voxel_height_sums" in a else {}),
                }
            )
            if not m.voxels.has_heights:
                lacks.append("point heights (object heights judged by voxel centres)")
            if "voxel_instance" in a:
                m.objects.instances.restore(a["voxel_instance"])
            else:
                lacks.append("saved object instances (segmented again on load)")
        except ConfigError as e:
            raise MapFormatError(f"{path}: {e}") from None
        for e, T in zip(a["frame_embeddings"], a["frame_poses"], strict=True):
            m.areas.add(e, T)
        try:
            m.sounds.segments = [AudioSegment(float(s0), float(s1)) for s0, s1 in h["segments"]]
        except (TypeError, ValueError) as e:
            raise MapFormatError(f"{path}: header 'segments' is malformed: {e}") from None
        m.sounds.embeddings = list(a["segment_embeddings"])
        m.sounds.positions = list(a["segment_positions"])
        if "segment_class_logits" in a:  # the open sound vocabulary's per-segment scores
            m.sounds.class_logits = list(a["segment_class_logits"])
            m.sounds.class_names = tuple(h["class_names"])
        m._frames_seen = int(h["frames_seen"])
        m.source = dict(h.get("source") or {})
        if h.get("visual") is not None:
            visual = {k.removeprefix("visual_"): v for k, v in a.items() if k.startswith("visual_")}
            try:
                db = VisualDatabase.from_state(h["visual"], visual)
            except VisualDatabaseError as e:
                raise VisualDatabaseError(f"{path}: {e}") from None
            visual_config = VisualModuleConfig(
                localization=db.config, target_px=target_px, target=target
            )
            m.images.database = db
            m.images.target_px = target_px
            m.images.target = visual_config.target
            m.config = replace(config, visual=visual_config)
        elif h["version"] == 1:
            lacks.append("the visual localization module (image goals are not found)")
        m.lacks = tuple(lacks)
        for what in lacks:
            log.info("%s (format %s) lacks %s", path, h["version"], what)
        return m

    def set_descriptions(self, descriptions) -> None:
        """Replace the vocabulary's descriptions (``MapConfig.descriptions``: query-time text,
        read by the object module; no voxel, instance or segment changes). ConfigError: a
        description of a name outside the vocabulary, or not a non-empty string."""
        self.config = replace(self.config, descriptions=descriptions)
        self.objects.set_descriptions(self.config.descriptions)

    @property
    def stats(self) -> MapStats:
        fused = (self._frames_seen + self.config.frame_step - 1) // self.config.frame_step
        return MapStats(
            self._frames_seen,
            fused,
            self.encoder_s,
            self.fusion_s,
            self.voxels.n,
            len(self.sounds),
            0 if self.visual is None else len(self.visual),
            self.visual_s,
        )

    # ------------------------------------------------------------------ queries
    def decay(self, major: bool) -> float:
        """The decay [1/m] of a primary (``major``) or auxiliary heatmap."""
        return (
            self.config.major_decay
            if check_bool("decay", "major", major)
            else self.config.aux_decay
        )

    def judge(self, modality: str, margin: float) -> tuple[float, bool]:
        """(calibrated confidence, found) of a query of ``modality`` whose best match beats
        the map's typical match by ``margin`` (a finite number)."""
        if (
            isinstance(margin, bool)
            or not isinstance(margin, (int, float, np.floating, np.integer))
            or not np.isfinite(margin)
        ):
            raise ConfigError(f"judge: margin must be a finite number, got {margin!r}")
        return self.calibration.judge(modality, float(margin), self.config.min_confidence)

    def query(self, kind: str, value, major: bool = True) -> Heatmap:
        """The heatmap of one query part: ``kind`` one of :data:`QUERY_KINDS` (``value`` a text,
        an :class:`AreaRef` for ``"area"``, or an (H, W, 3) uint8 image for ``"img"``), sharp
        (``major``) or broad."""
        check_bool("query", "major", major)
        name = QUERY_KINDS.get(kind)
        if name is None:
            raise ConfigError(f"unknown query kind {kind!r}; valid: {list(QUERY_KINDS)}")
        return getattr(self, name)(value, major=major)

    def object_heatmap(self, query: str, major: bool = True, viewpoint=None) -> Heatmap:
        """Heat around the voxels that best match ``query`` (the object module); a query of no
        words (no letter: emoji, punctuation, digits) is not found. ``viewpoint``: (x, y) [m]
        the robot's place, from which a nearest or farthest thing is ranked ("the nearest
        mug"); default the map frame's origin, the arm's base."""
        check_bool("object_heatmap", "major", major)
        q = _text(query, "object")
        if (h := self._wordless(q, "object", major)) is not None:
            return h
        if why := _unscorable(q):
            return Heatmap.not_found(self.grid, q, "object", self.decay(major), why)
        return self.objects.heatmap(q, self.decay(major), self.judge, viewpoint)

    def object_scores(self, query: str) -> tuple[np.ndarray, np.ndarray]:
        """Per occupied voxel: the query's cosine score, and whether it beats the background."""
        return self.objects.scores(_text(query, "object"))

    def sound_heatmap(self, query: str, major: bool = True) -> Heatmap:
        """Heat around where the sound best matching ``query`` was heard (the audio module); a
        query of no words is not found."""
        check_bool("sound_heatmap", "major", major)
        q = _text(query, "sound")
        if (h := self._wordless(q, "sound", major)) is not None:
            return h
        # words that name a thing on the table far better than any sound ask for no sound
        # ("the red mug"); a thing that sounds ("the duck") is near a sound too. The query's
        # sound reading is made once, for this check and for the heat.
        sound = None
        if len(self.sounds) and self.sounds.vocabulary is not None:
            sound = self.sounds.match(q, self.audio_text)
            if thing := self._rather_a_thing(q, THING_NOT_SOUND_MARGIN, sound):
                return Heatmap.not_found(self.grid, q, "sound", self.decay(major), thing)
        return self.sounds.heatmap(q, self.decay(major), self.audio_text, self.judge, sound)

    def _wordless(self, query: str, modality: str, major: bool) -> Heatmap | None:
        """Not found for a query that holds no word (not one letter: "🦒🦒", "...", "123"), or
        only words that name no particular thing ("the", "it"), or, for the default English
        text encoder, no letter of the Latin script ("كوب": it cannot read the words, and its
        nearest name would be noise); None for one that does."""
        if _SURROGATE.search(query):
            return None  # no text at all (a lone surrogate), which the encoder refuses
        if not _LETTER.search(query):
            why = f"{query!r} holds no words (no letter): it names nothing"
        elif self.text.space == MINILM_SPACE and not _LATIN.search(query):
            why = f"{query!r} is in a script the text encoder ({MINILM_SPACE}, English) cannot read"
        elif not (set(re.findall(r"[a-z]+", query.lower())) - FILLER_WORDS):
            why = f"{query!r} holds no word that names a thing, a sound or a place"
        else:
            return None
        return Heatmap.not_found(self.grid, query, modality, self.decay(major), why)

    def area_heatmap(self, query: AreaRef, major: bool = False) -> Heatmap:
        """Heat over a place on the table, found only where the reader's reading names one of
        this table.

        The words are read by the reader (:mod:`tabletop.reader.places`: ``get_reader().
        reference("area", text)``), which gives an :class:`AreaRef`; the map holds no words of
        places. A place named by where it is ("the left side of the table", "the far right
        corner") is a ``region`` of the table fitted from the map. A place named after what is
        there ("the area around the tray", "where the dog barked") has a ``subject``: heat
        around it where the object module finds that thing on the table, else where the audio
        module finds that sound: each decides by its own calibrated found / not-found (the
        object module's refusal of words that name nothing of the vocabulary, its operating
        point; the sound vocabulary's and the sound operating point). A reading with neither
        ("the area"), or a subject that is neither ("the kitchen", "the top shelf"), is not
        found, and the reason names why each module refused it."""
        check_bool("area_heatmap", "major", major)
        if isinstance(query, str):
            raise ConfigError(
                f"an area is read by the reader before the map scores it: pass "
                f"tabletop.reader.get_reader().reference('area', {query!r}) (an AreaRef), not "
                f"the words"
            )
        if not isinstance(query, AreaRef):
            raise ConfigError(f"an area query must be an AreaRef, got {type(query).__name__}")
        q = _text(query.text, "area")
        decay = self.decay(major)
        if (h := self._wordless(q, "area", major)) is not None:
            return h
        if query.region is not None:
            return region_heatmap(self.grid, self.table(), q, query.region, decay)
        subject = query.subject
        if subject is None:
            how = query.how if query.how.startswith("'") else "words for a place only"
            why = f"{q!r} names no region of this table and nothing on it ({how})"
            return Heatmap.not_found(self.grid, q, "area", decay, why)
        refusals = []
        h = self.objects.heatmap(subject, decay, self.judge)
        if h.found and not (unread := self._unnamed(subject)):
            return replace(h, query=q, modality="area")
        refusals.append(f"as a thing: {h.reason or unread}")
        if len(self.sounds):
            h = self.sounds.heatmap(subject, decay, self.audio_text, self.judge)
            if h.found and not (thing := self._rather_a_thing(subject)):
                return replace(h, query=q, modality="area")
            refusals.append(f"as a sound: {h.reason or thing}")
        why = f"{subject!r} names no region of this table and nothing on it ({'; '.join(refusals)})"
        return Heatmap.not_found(self.grid, q, "area", decay, why)

    def _reads_names(self) -> bool:
        """Whether the object module reads words against names (instances and a vocabulary;
        a map of voxel scores alone decides by its voxels' margin)."""
        return self.objects.uses_instances and bool(self.objects.vocabulary)

    def _unnamed(self, words: str) -> str:
        """Why ``words`` name no thing of the vocabulary by their own words ("" where they
        do): the object module's cosine rules (nearer no name than ``text_min`` unless the
        words are one name's own, or nearer another thing), without the kind reader's
        rescue. The reader learnt the names of things; asked a place it never saw, it names a
        kind with confidence ("the playground" read as a toy prism at 0.86, cosine 0.43), so a
        place is a thing here only where the words themselves say so."""
        if not self._reads_names():
            return ""  # no names to read the words against: the module's own decision
        m = self.objects.match(words)
        if m.forced:  # "the spot by something red": any object
            return ""
        return self.objects._cosine_refusal(
            m.words, m.text_score, m.nearest, m.described, m.other, m.other_score
        )

    def _rather_a_thing(self, words: str, margin: float = 0.0, sound=None) -> str:
        """Why ``words`` name a thing rather than a sound ("" where they name a sound): they
        lie nearer a vocabulary name, description or other thing of the object module than
        any phrasing of the sound vocabulary ("the kitchen" is nearer an oven than the sound
        of a washing machine, "the sofa" a couch; "where the dog barked" is nearer a dog
        barking than a dog). Decided by rank in the one text space both share; a sound
        encoder with its own text space, or without a vocabulary, leaves it to the audio
        module's own decision. ``margin``: how much nearer the thing must be; ``sound``:
        the words' reading by the audio module, where the caller has it."""
        if self.sounds.vocabulary is None or self.audio_text is not self.text:
            return ""
        if not self._reads_names():
            return ""
        if sound is None:
            sound = self.sounds.match(words, self.audio_text)
        if sound.text_score + margin > 1.0:
            return ""  # no cosine with a thing can lead by the margin: no object match needed
        m = self.objects.match(words)
        thing, score = (m.nearest, m.text_score)
        if m.other_score > score:
            thing, score = m.other, m.other_score
        if score < sound.text_score + margin:
            return ""
        heard = self.sounds.vocabulary.caption(sound.nearest)
        return (
            f"{words!r} names a thing rather than a sound: nearer {thing!r} ({score:.2f}) "
            f"than any sound ({heard!r}, {sound.text_score:.2f})"
        )

    def table(self) -> TableFit | None:
        """The table top fitted from the map (:func:`~tabletop.mapping.table_regions.fit_table`;
        None without one), cached until the voxels change."""
        key = (self.voxels.n, self.voxels.version)
        if self._table is None or self._table[0] != key:
            self._table = (key, fit_table(self.grid, self.voxels.indices))
        return self._table[1]

    def surfaces(self) -> list[TableFit]:
        """Every horizontal surface of the map, largest first
        (:func:`~tabletop.mapping.table_regions.fit_surfaces`: a room's floor, table tops,
        shelves), cached until the voxels change. Their heights come from the voxels' points
        where the segmentation judges heights so (``object.segmentation.heights``)."""
        key = (self.voxels.n, self.voxels.version)
        if self._surfaces is None or self._surfaces[0] != key:
            by_points = self.config.object.segmentation.heights == "points"
            heights = self.voxels.mean_heights() if by_points else None
            self._surfaces = (key, fit_surfaces(self.grid, self.voxels.indices, heights=heights))
        return self._surfaces[1]

    def supports(self) -> TableFit | list[TableFit] | None:
        """What the map's objects stand on, as its object config says
        (``object.segmentation.supports``): the fitted table, or every raised surface."""
        seg = self.config.object.segmentation
        if seg.supports == "table":
            return self.table()
        return raised_surfaces(self.surfaces(), seg.min_support_height_m)

    def image_heatmap(
        self, rgb: np.ndarray, major: bool = True, K: np.ndarray | None = None
    ) -> Heatmap:
        """Heat around the table point an image shows (the visual localization module); ``rgb``
        (H, W, 3) uint8 as the wrist camera would take it, ``K`` its intrinsics when its size is
        not the map's camera's. A failed localisation is not found with its reason."""
        check_bool("image_heatmap", "major", major)
        return self.images.heatmap(rgb, self.decay(major), self.judge, K)

    def localize(self, rgb: np.ndarray, K: np.ndarray | None = None) -> VisualLocalization:
        """Where the camera was when it took ``rgb`` (see :meth:`VisualModule.localize`)."""
        return self.images.localize(rgb, K)

    def photometric_check(self) -> PhotometricCheck:
        return self.images.photometric_check()

    def image_target(self, T_world_cam, K, image_size) -> np.ndarray:
        """(3,) [m]: the point an image taken from ``T_world_cam`` (a 4x4 rigid transform)
        shows at its centre, through the 3x3 intrinsics ``K``, for an image of ``image_size``
        (width, height) pixels."""
        for name, value, shape in (("T_world_cam", T_world_cam, (4, 4)), ("K", K, (3, 3))):
            a = np.asarray(value) if not isinstance(value, (str, bytes)) else None
            if a is None or a.shape != shape or not np.issubdtype(a.dtype, np.number):
                got = getattr(a, "shape", type(value).__name__)
                raise ConfigError(f"image_target: {name} must be a {shape} matrix, got {got}")
            if not np.isfinite(a).all():
                raise ConfigError(f"image_target: {name} holds a value that is not finite")
        T, k = np.asarray(T_world_cam, float), np.asarray(K, float)
        R = T[:3, :3]
        if not (np.allclose(R @ R.T, np.eye(3), atol=1e-4) and np.linalg.det(R) > 0
                and np.allclose(T[3], (0, 0, 0, 1), atol=1e-6)):  # fmt: skip
            raise ConfigError(
                "image_target: T_world_cam must be a rigid transform (an orthonormal rotation "
                "with determinant +1, last row 0 0 0 1)"
            )
        if not (k[0, 0] > 0 and k[1, 1] > 0 and np.allclose(k[2], (0, 0, 1), atol=1e-9)):
            raise ConfigError(
                "image_target: K must be pinhole intrinsics: focal lengths fx = K[0,0] and "
                f"fy = K[1,1] > 0, last row 0 0 1; got fx {k[0, 0]:g}, fy {k[1, 1]:g}, last "
                f"row {k[2].tolist()}"
            )
        size = np.asarray(image_size) if not isinstance(image_size, (str, bytes)) else None
        if (
            size is None
            or size.shape != (2,)
            or not np.issubdtype(size.dtype, np.number)
            or not (size > 0).all()
        ):
            raise ConfigError(
                f"image_target: image_size must be (width, height) in pixels, got {image_size!r}"
            )
        return self.images.image_target(T_world_cam, K, image_size)

    def get_max_pos_3d(self, heatmap: Heatmap) -> np.ndarray:
        """(3,) [m] world point of the heatmap's maximum (``targets.max_position``: ties
        resolve to the heaviest connected tied region; a top-down region is placed on the
        surface beneath). Raises :class:`~tabletop.errors.GoalNotFound` for a heatmap that
        found nothing or is zero everywhere."""
        if not isinstance(heatmap, Heatmap):
            raise ConfigError(
                f"get_max_pos_3d takes a Heatmap (from a query), got {type(heatmap).__name__}"
            )
        if heatmap.grid != self.grid:
            raise ConfigError(f"heatmap grid {heatmap.grid} is not this map's {self.grid}")
        return max_position(heatmap, self.voxels.occupancy())


#: A letter of any script: a query without one holds no word.
_LETTER = re.compile(r"[^\W\d_]")
_LATIN = re.compile(r"[A-Za-z\u00c0-\u024f]")
#: Half of a UTF-16 pair on its own: no character, not text.
_SURROGATE = re.compile("[\ud800-\udfff]")


#: How much nearer [cosine] a sound query's words must lie to a thing than to every sound for
#: the query to name a thing, not a sound: on the tune pools' 4464 sound phrasings the largest
#: such lead is 0.18 ("...drinking through a straw"); "the red mug" leads by 0.47.
THING_NOT_SOUND_MARGIN = 0.25


def _as_recording(recording) -> Recording:
    """``recording`` itself, or the recording on disk at that path; ConfigError naming what a
    map is built from for anything else."""
    if isinstance(recording, Recording):
        return recording
    if isinstance(recording, str | os.PathLike):
        return load_recording(recording)  # names a missing or foreign path
    raise ConfigError(
        f"a map is built from a Recording (tabletop.recording.load_recording(path), or "
        f"tabletop.sim.run_scan) or a recording's path, got {type(recording).__name__}"
    )


def _unscorable(query: str) -> str:
    """Why one thing's words hold what the object module cannot honour ("" where they hold
    none): a negation ("not the red mug"), an ordinal ("the second mug") or words relating it
    to another thing ("the mug near the duck"). Scored anyway, the words would find the thing
    they negate, any of the things, or either of the two."""
    read = (
        "ask it as an instruction ('tabletop run MAP \"go to ...\"', or "
        "tabletop.reader.understand() in Python), which says what it can do, or ask for a "
        "place on the table as an area (--area, area=)"
    )
    if negated := negations(query, describing=True):
        return f"{query!r} negates what it names ({negated[0]!r}): {read}"
    if (o := ordinal(query)) is not None:
        return f"{query!r} picks by order ({o!r}), which the map does not rank: {read}"
    if (rel := relation_words(query)) is not None:
        return f"{query!r} relates two things ({rel!r}), and one thing's words are scored: {read}"
    return ""


def _text(query, what: str) -> str:
    """The query's words, compatibility-normalised (NFKC: full-width letters are letters);
    a query that is not a non-empty line of text is a :class:`ConfigError`."""
    if not isinstance(query, str) or not query.strip():
        raise ConfigError(f"a {what} query is a non-empty string, got {query!r}")
    if any(unicodedata.category(c) == "Cc" for c in query):  # C0 and C1 controls
        raise ConfigError(
            f"a {what} query is one line of words; {query!r} holds a control character "
            "(a line break, a tab or a terminal escape)"
        )
    if not _LETTER.search(query):
        return query  # no letter: no words, whatever compatibility forms would make of it
    return unicodedata.normalize("NFKC", query)
