"""Visual localization: where was an image of the table taken, given the map's reference frames?

The paper's visual localization module (AVLMaps, "Visual localization"): a query image is
matched against reference frames of the scan — retrieval of the most similar frames, local
feature matching, then PnP-RANSAC on the reference keypoints' 3D points (back-projected with
the reference frame's metric depth) — and the result is the query camera's pose in the world
(robot base) frame. :class:`~tabletop.mapping.avlmap.AVLMap` turns it into the heatmap
``H_v(p) = max(1 - eps * d_xy(p, p_v), 0)``.

Typical use::

    from tabletop.mapping.visual import (
        VisualLocalizationConfig,
        build_visual_database,
        localize_image,
    )

    db = build_visual_database(recording, VisualLocalizationConfig(matcher="sift"))
    loc = localize_image(db, rgb)   # a VisualLocalization; a failure is a reason, not a raise

One idea per module, each importing only those above it:

- :mod:`~tabletop.mapping.visual.localization`: the values — :class:`VisualLocalizationConfig`
  (:data:`MATCHERS`), the result :class:`VisualLocalization` (``ok`` with the pose, or
  ``ok=False`` with a reason) and :func:`look_at_point`.
- :mod:`~tabletop.mapping.visual.inputs`: :func:`check_rgb` and the intrinsics check.
- :mod:`~tabletop.mapping.visual.photometric`: :class:`PhotometricCheck`, does the map seen
  from a candidate pose look like the query image?
- :mod:`~tabletop.mapping.visual.features`: the local feature backends (``"xfeat"``: XFeat +
  LighterGlue; ``"sift"``: OpenCV SIFT), :data:`DESCRIPTOR_DIMS`.
- :mod:`~tabletop.mapping.visual.database`: :class:`VisualDatabase` (behaviour), the
  reference frames, built frame by frame (:func:`build_visual_database` is the same loop over
  a recording), retrieval by descriptor votes, and its persistence inside the map file
  (:data:`STATE_ARRAYS`, :class:`VisualDatabaseError`).
- :mod:`~tabletop.mapping.visual.localize`: :func:`localize_image`, the query pipeline. A
  failed localisation is never an exception; malformed input (wrong shape or dtype) raises
  :class:`~tabletop.errors.ConfigError`.
"""

from tabletop.mapping.visual.database import (
    STATE_ARRAYS,
    VisualDatabase,
    VisualDatabaseError,
    build_visual_database,
)
from tabletop.mapping.visual.features import DESCRIPTOR_DIMS
from tabletop.mapping.visual.inputs import check_rgb
from tabletop.mapping.visual.localization import (
    MATCHERS,
    VisualLocalization,
    VisualLocalizationConfig,
    look_at_point,
)
from tabletop.mapping.visual.localize import localize_image
from tabletop.mapping.visual.photometric import PhotometricCheck

__all__ = [
    "DESCRIPTOR_DIMS",
    "MATCHERS",
    "STATE_ARRAYS",
    "PhotometricCheck",
    "VisualDatabase",
    "VisualDatabaseError",
    "VisualLocalization",
    "VisualLocalizationConfig",
    "build_visual_database",
    "check_rgb",
    "localize_image",
    "look_at_point",
]
