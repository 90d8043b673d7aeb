"""The query pipeline of visual localization: :func:`localize_image` matches a query image with
the best-voted reference frames of a :class:`~tabletop.mapping.visual.database.VisualDatabase`,
solves PnP-RANSAC on the 2D-3D matches and, given a
:class:`~tabletop.mapping.visual.photometric.PhotometricCheck`, checks each candidate pose
against the map. It returns a
:class:`~tabletop.mapping.visual.localization.VisualLocalization`: ``ok`` with the pose, or
``ok=False`` with a reason. A failed localisation is never an exception; malformed input
(wrong shape or dtype) raises :class:`~tabletop.errors.ConfigError`.
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from tabletop.mapping.visual.database import VisualDatabase
from tabletop.mapping.visual.features import _backend, _Features
from tabletop.mapping.visual.inputs import _check_K, check_rgb
from tabletop.mapping.visual.localization import (
    VisualLocalization,
    VisualLocalizationConfig,
    look_at_point,
)
from tabletop.mapping.visual.photometric import PhotometricCheck

__all__ = ["localize_image", "searched_poses"]


def _unturn(xy: np.ndarray, k: int, width: int, height: int) -> np.ndarray:
    """(N, 2) pixel coordinates in an image of ``width x height`` of points ``xy`` found in
    ``np.rot90(image, k)``."""
    x, y = xy[:, 0], xy[:, 1]
    w, h = width - 1, height - 1
    out = {0: (x, y), 1: (w - y, x), 2: (w - x, h - y), 3: (y, h - x)}[k % 4]
    return np.stack(out, axis=1).astype(np.float32)


def _pnp(
    pts_world: np.ndarray, xy: np.ndarray, K: np.ndarray, config: VisualLocalizationConfig
) -> tuple[np.ndarray | None, int]:
    """Query camera pose T_world_cam (4, 4) from 2D-3D matches, and its inlier count."""
    cv2.setRNGSeed(0)
    xy = xy.astype(np.float64)
    ok, rvec, tvec, inl = cv2.solvePnPRansac(
        pts_world,
        xy,
        K,
        None,
        iterationsCount=config.ransac_iterations,
        reprojectionError=config.reprojection_px,
        confidence=0.999,
        flags=cv2.SOLVEPNP_SQPNP,
    )
    if not ok or inl is None or len(inl) < 4:
        return None, 0 if inl is None else len(inl)
    inl = inl.ravel()
    rvec, tvec = cv2.solvePnPRefineLM(pts_world[inl], xy[inl], K, None, rvec, tvec)
    proj, _ = cv2.projectPoints(pts_world, rvec, tvec, K, None)
    n_inl = int(np.sum(np.linalg.norm(proj.reshape(-1, 2) - xy, axis=1) <= config.reprojection_px))
    R = cv2.Rodrigues(rvec)[0]
    T = np.eye(4)
    T[:3, :3] = R.T
    T[:3, 3] = -R.T @ tvec.ravel()
    return (T, n_inl) if np.all(np.isfinite(T)) else (None, 0)


class _TurnedQuery:
    """The query image turned by ``k`` quarter turns (``np.rot90``): its features (keypoints
    turned back to the unturned image), reference frames by retrieval votes, and matches with
    each reference frame, computed once."""

    def __init__(self, database: VisualDatabase, backend, rgb: np.ndarray, k: int) -> None:
        turned = np.ascontiguousarray(np.rot90(rgb, k))
        xy_t, desc = backend.extract(turned, database.config.max_keypoints)
        self.k = k
        self.features = _Features(xy_t, desc, (turned.shape[1], turned.shape[0]))
        self.xy = _unturn(xy_t, k, rgb.shape[1], rgb.shape[0])
        self.order = np.argsort(-database.retrieve(desc), kind="stable")
        self._database, self._backend = database, backend
        self._matches: dict[int, np.ndarray] = {}

    def matches(self, j: int) -> np.ndarray:
        """(K, 2) rows (query keypoint, keypoint of reference frame ``j``)."""
        if j not in self._matches:
            db = self._database
            f = db._frames[j]
            ref = _Features(f["xy"], f["desc"], db.image_size)
            self._matches[j] = self._backend.match(self.features, ref, db.config)
        return self._matches[j]


def _localize_turned(
    database: VisualDatabase, query: _TurnedQuery, K, n_frames: int, min_inliers: int
) -> dict:
    """One pose candidate: the turned query matched with the ``n_frames`` reference frames it
    votes for most, all 2D-3D matches in one PnP-RANSAC. Returns ``T`` (None and a ``reason``
    when it fails), ``inliers``, ``matches``, ``references`` and the ``turn``."""
    config = database.config
    order = query.order[:n_frames]
    refs = tuple(database._frames[j]["index"] for j in order)
    out = {"T": None, "inliers": 0, "matches": 0, "references": refs, "turn": query.k}
    pts, img = [np.zeros((0, 3))], [np.zeros((0, 2), np.float32)]
    for j in order:
        m = query.matches(int(j))
        pts.append(database._frames[j]["points"][m[:, 1]])
        img.append(query.xy[m[:, 0]])
    pts, img = np.concatenate(pts), np.concatenate(img)
    out["matches"] = len(pts)
    if len(pts) < min_inliers:
        return {**out, "reason": f"{len(pts)} matches with reference frames {list(refs)}"}
    T, n_inl = _pnp(pts, img, K, config)
    out["inliers"] = n_inl
    if T is None or n_inl < min_inliers or n_inl < config.min_inlier_ratio * len(pts):
        return {**out, "reason": f"{n_inl} of {len(pts)} matches with frames {list(refs)} agree"}
    if config.require_look_down and look_at_point(T) is None:
        return {**out, "reason": f"a pose with {n_inl} inliers does not look down at the table"}
    return {**out, "T": T, "reason": ""}


def _rare_needed(kappa: float, config) -> float:
    """The share of an image's rare colours a searched pose of ``kappa`` must reproduce."""
    if kappa >= config.search_strong_kappa:
        return config.search_min_rare_agreement
    return max(config.search_min_rare_agreement, config.search_weak_rare_agreement)


def _checked(cand: dict, check: PhotometricCheck, rgb, K, config, d=None) -> dict:
    """``cand`` with its photometric ``coverage`` and ``agreement``; its pose dropped (with a
    reason) when the check refuses it. ``d``: the check's details of the pose, when known."""
    if cand["T"] is None:
        return cand
    d = d if d is not None else check.details(cand["T"], K, rgb, config)
    cov, agree, kappa = d["coverage"], d["agreement"], d["kappa"]
    cand = {**cand, "coverage": cov, "agreement": agree, "kappa": kappa}
    pose = (
        "the best pose the map search found"
        if cand.get("searched")
        else f"a pose with {cand['inliers']} inliers"
    )
    if cov < config.min_coverage:
        reason = f"{pose} sees the map in {cov:.0%} of the image (need {config.min_coverage:.0%})"
    elif agree < config.min_agreement:
        reason = (
            f"{pose} reproduces {agree:.0%} of the image's colours from the map "
            f"(need {config.min_agreement:.0%})"
        )
    elif kappa < config.min_kappa:
        reason = (
            f"{pose} agrees with the map hardly beyond chance "
            f"(kappa {kappa:.2f}, need {config.min_kappa})"
        )
    elif cand.get("searched") and kappa < config.search_min_kappa:
        reason = (
            f"{pose} agrees with the map too little beyond chance for a searched pose "
            f"(kappa {kappa:.2f}, need {config.search_min_kappa})"
        )
    elif cand.get("searched") and d["rare"] < config.search_min_rare:
        reason = (
            f"the image shows too little that sets a place apart ({d['rare']} sample pixels "
            f"of colours rare in the map, need {config.search_min_rare}): only floor, walls "
            f"or furniture the whole map has"
        )
    elif cand.get("searched") and d["rare_agreement"] < _rare_needed(kappa, config):
        reason = (
            f"{pose} reproduces the image's floor and walls but {d['rare_agreement']:.0%} of "
            f"its rare colours (need {_rare_needed(kappa, config):.0%} at kappa {kappa:.2f}): "
            f"the image was not taken in this map"
        )
    else:
        return cand
    return {**cand, "T": None, "reason": reason}


def searched_poses(search, check: PhotometricCheck, rgb, K, config) -> list[tuple]:
    """The map search's best candidate poses for ``rgb``, each refined
    (:meth:`PhotometricCheck.refine_upright`) where it could pass the check (enough of the
    map and of the map's rare colours in view): ``(T_world_cam, details)`` pairs in the
    search's order, ``details`` as :meth:`PhotometricCheck.details` gives them for the pose.
    Empty without a search or a place to search from."""
    s = search() if search is not None else None
    if s is None:
        return []
    out = []
    for _, T in s.candidates(rgb, K, config.search_candidates):
        d = check.details(T, K, rgb, config)
        if d["coverage"] >= config.min_coverage and d["rare"] >= config.search_min_rare:
            T2, _ = check.refine_upright(T, K, rgb, config)
            d2 = check.details(T2, K, rgb, config)
            if d2["agreement"] > d["agreement"]:
                T, d = T2, d2
        out.append((T, d))
    return out


def _searched(search, check: PhotometricCheck, rgb, K, config) -> dict | None:
    """The best of the map search's (refined) candidate poses as the photometric check judges
    them (None: no search, or no place to search from)."""
    best = None
    for T, d in searched_poses(search, check, rgb, K, config):
        cand = {"T": T, "inliers": 0, "matches": 0, "references": (), "searched": True}
        cand = _checked(cand, check, rgb, K, config, d)
        key = (cand["T"] is not None, cand["agreement"])
        if best is None or key > (best["T"] is not None, best["agreement"]):
            best = cand
    return best


#: How much more of the image a searched pose must reproduce to replace a matched one.
SEARCH_OVERRULES_BY = 0.05


def _better_searched(search, check: PhotometricCheck, rgb, K, config, matched: dict):
    """The map search's (refined) pose that passes the check's plain tests (as a matched pose
    does) and reproduces at least :data:`SEARCH_OVERRULES_BY` more of the image than the
    ``matched`` candidate, with no less kappa; None when there is none."""
    best = None
    for T, d in searched_poses(search, check, rgb, K, config):
        cand = {"T": T, "inliers": 0, "matches": 0, "references": ()}
        cand = _checked(cand, check, rgb, K, config, d)
        if cand["T"] is None:
            continue
        if (
            cand["agreement"] >= matched["agreement"] + SEARCH_OVERRULES_BY
            and cand["kappa"] >= matched["kappa"]
            and (best is None or cand["agreement"] > best["agreement"])
        ):
            best = {**cand, "searched": True}
    return best


def localize_image(
    database: VisualDatabase,
    rgb: np.ndarray,
    K: np.ndarray | None = None,
    check: PhotometricCheck | None = None,
    search=None,
) -> VisualLocalization:
    """Pose of the camera that took ``rgb`` (H, W, 3) uint8, in the database's world frame.

    ``K`` (3, 3) [px] is the query camera's intrinsics (default: the reference frames').
    The ``top_n`` reference frames with the most retrieval votes are matched with the
    database's matcher; their 2D-3D matches enter one PnP-RANSAC. A descriptor that is not
    rotation invariant (XFeat) tries the query turned by 0, 90, 180 and 270 degrees. When no
    candidate counts, each turn is tried once more with the ``2 * top_n`` best-voted frames.

    Without ``check`` a pose counts with ``min_inliers`` inliers, ``min_inlier_ratio`` of the
    matches and the camera looking down at the table (a wrist camera always does); the one
    with the most inliers wins. With a :class:`PhotometricCheck` of the map, candidates need
    only ``verify_min_inliers`` inliers but must reproduce the image (``min_coverage``,
    ``min_agreement``, ``min_kappa``); the best-agreeing one wins, and one that agrees surely
    (``sure_agreement``, ``sure_kappa``) ends the search. When no matched pose counts and
    ``search`` (a callable returning the map's
    :class:`~tabletop.mapping.visual.panorama.PanoramaSearch`, or None) is given with a check
    and the config's ``search`` is on, the check judges the map search's best poses the same
    way (the result's ``searched`` is then True); a matched pose that is not sure is compared
    with the search's poses, and one that reproduces the image clearly better replaces it
    (:data:`SEARCH_OVERRULES_BY`). Returns ``ok=False`` with a reason when
    nothing counts; raises :class:`ConfigError` only for malformed input.
    """
    t0 = time.perf_counter()
    config = database.config
    rgb = check_rgb(rgb)
    K = database.K if K is None else _check_K(K)

    def fail(reason: str, **kw) -> VisualLocalization:
        return VisualLocalization(False, reason, None, None, time_s=time.perf_counter() - t0, **kw)

    if len(database) == 0:
        return fail("the map has no reference frames")
    grey_std = float(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).std())
    if grey_std < config.min_image_std:
        return fail(f"blank image (grey std {grey_std:.2f} < {config.min_image_std})")
    backend = _backend(config.matcher)
    turns = (0,) if backend.rotation_invariant or config.upright else (0, 1, 2, 3)
    queries: dict[int, _TurnedQuery] = {}

    def turned(k: int) -> _TurnedQuery:  # features extracted once, when first needed
        if k not in queries:
            queries[k] = _TurnedQuery(database, backend, rgb, k)
        return queries[k]

    min_inliers = config.min_inliers if check is None else config.verify_min_inliers

    def rank(c: dict) -> tuple:
        return (c["T"] is not None, c.get("agreement") or 0.0, c["inliers"])

    def sure(c: dict) -> bool:
        return c["T"] is not None and (
            c["agreement"] >= config.sure_agreement and c["kappa"] >= config.sure_kappa
        )

    best = None
    for n_frames in dict.fromkeys((config.top_n, min(2 * config.top_n, len(database)))):
        for k in turns:
            q = turned(k)
            cand = _localize_turned(database, q, K, n_frames, min_inliers)
            if check is not None:
                cand = _checked(cand, check, rgb, K, config)
            if best is None or rank(cand) > rank(best):
                best = cand
            if check is not None and sure(best):
                break
        if best["T"] is not None:
            break
    if best["T"] is None and check is not None and config.search:
        found = _searched(search, check, rgb, K, config)
        if found is not None and (found["T"] is not None or not best.get("agreement")):
            best = found
    elif check is not None and config.search and not sure(best):
        # A matched pose that is not sure may be a wrong place that a few matches among
        # repeated textures support: the map search's pose replaces it where it reproduces
        # the image clearly better (the matches already say the image is of this map).
        better = _better_searched(search, check, rgb, K, config, best)
        if better is not None:
            best = better
    kw = {k: best[k] for k in ("inliers", "matches", "references")}
    kw["searched"] = bool(best.get("searched"))
    kw.update({k: best[k] for k in ("agreement", "kappa", "coverage") if k in best})
    if best["T"] is None:
        need = (
            f"need {min_inliers} inliers and {config.min_inlier_ratio:.0%} of the matches"
            if check is None
            else f"need {min_inliers} inliers and {config.min_agreement:.0%} agreement with the map"
        )
        return fail(f"no pose found ({need}): {best['reason']}", **kw)
    T = best["T"]
    return VisualLocalization(True, "", T, look_at_point(T), time_s=time.perf_counter() - t0, **kw)
