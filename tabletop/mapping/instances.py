"""Object instances segmented from the map's geometry: the object module's unit.

:func:`segment_instances` splits the occupied voxels into objects without any label:

1. the supporting surface is fitted from the map (:func:`~tabletop.mapping.table_regions.fit_table`:
   the densest horizontal layer, not ground truth);
2. voxels above that surface and over it are connected (26-neighbourhood) into components;
3. a component is split where the measured colour changes sharply between neighbouring
   voxels (CIELAB ΔE above ``split_delta_e``) *and* the fused features change too (cosine
   below ``split_cos``) — two objects that touch — or where the features alone change
   strongly (cosine below ``split_cos_alone``: two touching objects of one colour, which
   colour cannot tell apart; one object's two colours, a soccer ball's panels, keep their
   features alike and stay joined), or, with ``split_crease_m``, where the top surface folds
   upwards between two columns (a flat top meeting a rising flank) and the features change
   somewhat (cosine below ``split_cos_shape``), and fragments smaller than
   ``min_voxels`` rejoin the neighbour they touch most; components smaller than
   ``min_voxels`` are dropped (specks, sensor noise).

Each :class:`ObjectInstance` keeps its voxels (rows of the :class:`VoxelMap`), centre, extent,
measured colour (mean RGB over every fused pixel, and CIELAB) and fused embedding: the mean of
every pixel feature fused into its voxels, so every view of every voxel votes, and a view that
saw the object closer or more squarely (more pixels per voxel) weighs more.

Segmentation is a pure function of the voxels: a map built frame by frame (online) and one
built in batch give the same instances, and :class:`InstanceSet` caches them until the voxels
change.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from tabletop.errors import ConfigError
from tabletop.mapping.colors import delta_e, rgb_to_lab
from tabletop.mapping.table_regions import TableFit
from tabletop.mapping.voxel_map import VoxelMap

__all__ = [
    "PALETTE_MIN_DELTA_E",
    "InstanceConfig",
    "InstanceSet",
    "ObjectInstance",
    "colour_palette",
    "instances_from_labels",
    "segment_instances",
    "support_of",
]


#: What :attr:`InstanceConfig.supports` may name.
SUPPORTS = ("table", "surfaces")
#: What :attr:`InstanceConfig.heights` may name.
HEIGHTS = ("voxel", "points")


@dataclass(frozen=True)
class InstanceConfig:
    """How the map's voxels are split into object instances."""

    min_voxels: int = 6
    """Smaller components are dropped; smaller fragments of a split rejoin a neighbour."""
    above_table_m: float = 0.006
    """A voxel belongs to an object when its centre is this far [m] above the fitted table."""
    table_margin_m: float = 0.03
    """...and lies over the table, within this margin [m] of its fitted edges."""
    split_delta_e: float = 25.0
    """Neighbouring voxels whose colours differ by more than this CIELAB ΔE..."""
    split_cos: float = 0.9
    """...and whose fused features' cosine is below this belong to different objects."""
    split_cos_alone: float = 0.6
    """Neighbouring voxels whose fused features' cosine is below this belong to different
    objects whatever their colours (two objects of one colour that touch); -1: never."""
    split_crease_m: float | None = None
    """Neighbouring voxels whose columns meet in a crease of the top surface — the column
    heights' second difference across their boundary above this [m]: a flat top meeting a
    rising flank, where one object leans on another — belong to different objects when their
    fused features' cosine is also below :attr:`split_cos_shape` (two touching objects of one
    colour whose features alone are too alike to cut); None: shape never cuts. Room maps cut
    at 1.5 cm (:func:`~tabletop.eval.room.room_map_settings`): over the room suites' and the
    arm's default suite's maps it parts the one pair the default encoders merged (a blue brick
    against a blue ball) and splits no object (``tools/instance_split_report.py``); the arm's
    maps keep it off until its suites are measured with it."""
    split_cos_shape: float = 0.9
    """...the fused features' cosine below which a crease cuts (a crease inside one object,
    a teddy bear's arm against its belly, keeps its features alike and stays joined)."""
    supports: str = "table"
    """What objects stand on: "table" (the map's one fitted table: a tabletop scan) or
    "surfaces" (every horizontal surface :data:`min_support_height_m` above the lowest one,
    :func:`~tabletop.mapping.table_regions.fit_surfaces`: a room's table tops and shelves)."""
    min_support_height_m: float = 0.2
    """With ``supports="surfaces"``: how far [m] above the lowest surface (the floor) a
    surface must be to carry objects."""
    max_height_m: float | None = None
    """A voxel more than this [m] above its support is not an object's (None: no bound; a
    room's shelves above a table are not on it)."""
    heights: str = "voxel"
    """How high a voxel is, for the tests above: "voxel" (its centre) or "points" (the mean
    height of the points fused into it, where the map knows them). With voxels as tall as a
    flat object (a room's 3 cm), the object lies in the table top's own voxel layer and only
    the points' heights tell the two apart; the surfaces' heights are then measured from the
    points too (:func:`~tabletop.mapping.table_regions.fit_surfaces`)."""

    def __post_init__(self) -> None:
        if self.supports not in SUPPORTS:
            raise ConfigError(f"supports must be one of {list(SUPPORTS)}, got {self.supports!r}")
        if self.heights not in HEIGHTS:
            raise ConfigError(f"heights must be one of {list(HEIGHTS)}, got {self.heights!r}")
        if not self.min_support_height_m >= 0:
            raise ConfigError(
                f"min_support_height_m must be >= 0 [m], got {self.min_support_height_m!r}"
            )
        if self.max_height_m is not None and not self.max_height_m > 0:
            raise ConfigError(f"max_height_m must be > 0 [m] or None, got {self.max_height_m!r}")
        if self.min_voxels < 1:
            raise ConfigError(f"min_voxels must be >= 1, got {self.min_voxels}")
        if not self.above_table_m >= 0 or not self.table_margin_m >= 0:
            raise ConfigError("above_table_m and table_margin_m must be >= 0 [m]")
        if not self.split_delta_e > 0 or not -1 <= self.split_cos <= 1:
            raise ConfigError(
                f"split_delta_e must be > 0 and split_cos in [-1, 1], got "
                f"{self.split_delta_e}, {self.split_cos}"
            )
        if self.split_crease_m is not None and not self.split_crease_m > 0:
            raise ConfigError(
                f"split_crease_m must be > 0 [m] or None, got {self.split_crease_m!r}"
            )
        if not -1 <= self.split_cos_shape <= 1:
            raise ConfigError(f"split_cos_shape must be in [-1, 1], got {self.split_cos_shape!r}")
        if not -1 <= self.split_cos_alone <= self.split_cos:
            raise ConfigError(
                f"split_cos_alone must be in [-1, split_cos={self.split_cos}], got "
                f"{self.split_cos_alone}"
            )


@dataclass(frozen=True, eq=False)
class ObjectInstance:
    """One object segmented from the map."""

    id: int
    rows: np.ndarray
    """(n,) rows of the instance's voxels in the :class:`VoxelMap`."""
    center: np.ndarray
    """(3,) [m] the mean of its voxel centres."""
    lo: np.ndarray
    """(3,) [m] the low corner of its voxels' bounding box."""
    hi: np.ndarray
    """(3,) [m] the high corner."""
    rgb: np.ndarray
    """(3,) the mean colour (0-255) of every pixel fused into it."""
    lab: np.ndarray
    """(3,) that colour in CIELAB."""
    embedding: np.ndarray
    """(dim,) unit: the mean of every pixel feature fused into it."""
    points: int
    """Pixels fused into it."""
    palette: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """(k, 3) CIELAB: its distinct colours (k <= 2), largest share first
    (:func:`colour_palette`); empty where one colour describes it."""
    palette_share: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(k,) the share of its surface (voxels) in each palette colour."""

    @property
    def extent(self) -> np.ndarray:
        """(3,) [m] size of its bounding box."""
        return self.hi - self.lo

    @property
    def voxels(self) -> int:
        return len(self.rows)


#: The 13 offsets that reach each of the 26 neighbours of a voxel once per pair.
_HALF_NEIGHBOURHOOD = [
    np.array(o) - 1 for o in np.ndindex(3, 3, 3) if (np.array(o) - 1).tolist() > [0, 0, 0]
]


def _as_supports(table) -> list[TableFit]:
    if table is None:
        return []
    if isinstance(table, TableFit):
        return [table]
    return list(table)


def support_of(supports, point: np.ndarray) -> TableFit | None:
    """The highest of ``supports`` (a :class:`TableFit`, a list of them, or None) under
    ``point`` (3,) [m]: the one whose extent holds its x, y and whose top is below it (the
    largest when none does)."""
    sup = _as_supports(supports)
    under = [
        s
        for s in sup
        if s.x[0] <= point[0] <= s.x[1] and s.y[0] <= point[1] <= s.y[1] and s.z <= point[2]
    ]
    if under:
        return max(under, key=lambda s: s.z)
    return sup[0] if sup else None


def segment_instances(
    voxels: VoxelMap, table, config: InstanceConfig | None = None
) -> list[ObjectInstance]:
    """The object instances of ``voxels`` standing on ``table`` (a :class:`TableFit`, or a list
    of supporting surfaces; none without one), largest first (see the module docstring)."""
    config = config or InstanceConfig()
    supports = _as_supports(table)
    if not supports or voxels.n == 0:
        return []
    centers = voxels.centers
    heights = voxels.mean_heights() if config.heights == "points" else None
    z = centers[:, 2] if heights is None else heights
    m = config.table_margin_m
    top = np.inf if config.max_height_m is None else config.max_height_m
    inside = np.zeros(voxels.n, bool)
    for sup in sorted(supports, key=lambda s: s.z):
        over = (
            (centers[:, 0] >= sup.x[0] - m)
            & (centers[:, 0] <= sup.x[1] + m)
            & (centers[:, 1] >= sup.y[0] - m)
            & (centers[:, 1] <= sup.y[1] + m)
        )
        # A higher support over this one (a shelf board over a shelf board) ends its objects.
        inside = np.where(
            over & (z > sup.z - config.above_table_m),
            (z > sup.z + config.above_table_m) & (z <= sup.z + top),
            inside,
        )
    cand = np.nonzero(inside)[0]
    if len(cand) < config.min_voxels:
        return []
    idx = voxels.indices[cand]
    lo = idx.min(axis=0)
    sub = idx - lo
    dense = np.full(tuple(sub.max(axis=0) + 1), -1, np.int64)
    dense[tuple(sub.T)] = np.arange(len(cand))

    feats = voxels.mean_features()[cand]
    rgb = voxels.mean_colors()[cand].astype(np.float64)
    lab = rgb_to_lab(rgb)
    # Neighbour pairs (26-neighbourhood, each pair once), and whether they stay joined.
    a_list, b_list = [], []
    for off in _HALF_NEIGHBOURHOOD:
        nb = sub + off
        ok = np.all((nb >= 0) & (nb < dense.shape), axis=1)
        j = np.full(len(sub), -1, np.int64)
        j[ok] = dense[tuple(nb[ok].T)]
        has = j >= 0
        a_list.append(np.nonzero(has)[0])
        b_list.append(j[has])
    a = np.concatenate(a_list)
    b = np.concatenate(b_list)
    de = delta_e(lab[a], lab[b])
    cos = np.einsum("ij,ij->i", feats[a], feats[b])
    cut = ((de > config.split_delta_e) & (cos < config.split_cos)) | (cos < config.split_cos_alone)
    if config.split_crease_m is not None:
        crease = _creases(sub, z[cand], a, b) > config.split_crease_m
        cut |= crease & (cos < config.split_cos_shape)
    keep = ~cut
    g = coo_matrix((np.ones(int(keep.sum())), (a[keep], b[keep])), shape=(len(cand),) * 2)
    _, frag = connected_components(g, directed=False)
    frag = _absorb_small(frag, a, b, config.min_voxels)

    sizes = np.bincount(frag)
    big = [f for f in np.argsort(-sizes, kind="stable") if sizes[f] >= config.min_voxels]
    labels = np.full(voxels.n, -1, np.int64)
    for k, f in enumerate(big):
        labels[cand[frag == f]] = k
    return instances_from_labels(voxels, labels)


#: The steps across a column a fold is measured along: the two axes and the two diagonals.
_FOLD_STEPS = ((1, 0), (0, 1), (1, 1), (1, -1))


def _creases(sub: np.ndarray, z: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(pairs,) [m] how sharply the top surface folds upwards at or beside the columns of
    voxels ``a`` and ``b`` (rows of ``sub``, (n, 3) grid indices; ``z`` (n,) [m] their
    heights): the largest concavity of a column within one column of either, a column's
    concavity being the largest second difference of the column tops H across it,
    H(c - u) + H(c + u) - 2 H(c), over the four directions u (along the axes and the
    diagonals, so that a fold running at any angle is seen). Positive where a
    flat or falling surface meets a rising one (two objects leaning together); at most a
    voxel's rounding on one convex object; -inf for a vertical pair, or where no direction has
    both neighbouring columns seen (a hole or an edge is no crease)."""
    from scipy.ndimage import maximum_filter  # only maps that split on shape pay its import

    cols = sub[:, :2]
    lo = cols.min(axis=0) - 1
    shape = tuple(cols.max(axis=0) - lo + 2)
    top = np.full(shape, -np.inf)
    np.maximum.at(top, tuple((cols - lo).T), z)
    seen = np.isfinite(top)
    fold = np.full(shape, -np.inf)
    inner = (slice(1, -1), slice(1, -1))
    for dx, dy in _FOLD_STEPS:
        before = top[1 - dx : shape[0] - 1 - dx, 1 - dy : shape[1] - 1 - dy]
        after = top[1 + dx : shape[0] - 1 + dx, 1 + dy : shape[1] - 1 + dy]
        with np.errstate(invalid="ignore"):
            d = np.where(np.isfinite(before) & np.isfinite(after), before + after, -np.inf)
            fold[inner] = np.maximum(
                fold[inner], np.where(seen[inner], d - 2 * top[inner], -np.inf)
            )
    # a fold reaches the columns around it: where two objects meet only at a corner or along a
    # low flank, the pairs there pass beside the folded columns, not through them
    near = maximum_filter(fold, size=3, mode="constant", cval=-np.inf)
    ca, cb = tuple((cols[a] - lo).T), tuple((cols[b] - lo).T)
    out = np.maximum(near[ca], near[cb])
    out[np.all(cols[a] == cols[b], axis=1)] = -np.inf  # one column: no fold between them
    return out


def _absorb_small(frag, a, b, min_voxels: int) -> np.ndarray:
    """Fragments below ``min_voxels`` join the neighbouring fragment they share the most voxel
    faces with (repeated until none can move)."""
    frag = np.asarray(frag).copy()
    for _ in range(8):
        sizes = np.bincount(frag)
        small = sizes[frag] < min_voxels
        fa, fb = frag[a], frag[b]
        cross = (fa != fb) & (small[a] | small[b])
        if not cross.any():
            break
        # For each small fragment, its most-shared neighbour that is larger than itself.
        src = np.concatenate([fa[cross & small[a]], fb[cross & small[b]]])
        dst = np.concatenate([fb[cross & small[a]], fa[cross & small[b]]])
        if not len(src):
            break
        pairs, n = np.unique(np.stack([src, dst], 1), axis=0, return_counts=True)
        order = np.lexsort((-sizes[pairs[:, 1]], -n, pairs[:, 0]))
        best: dict[int, int] = {}
        for s, t in pairs[order]:
            if int(s) not in best and sizes[t] >= sizes[s]:
                best[int(s)] = int(t)
        if not best:
            break
        for s, t in best.items():
            frag[frag == s] = t
    return frag


class InstanceSet:
    """The instances of a map's voxels, segmented when first asked for and again only after
    the voxels change (online maps stay current)."""

    def __init__(self, voxels: VoxelMap, table, config: InstanceConfig | None = None) -> None:
        self.voxels = voxels
        self._table = table  # () -> TableFit | None (the map's cached fit)
        self.config = config or InstanceConfig()
        self._key: tuple[int, int] | None = None
        self._items: list[ObjectInstance] = []
        self._labels: np.ndarray | None = None

    def _refresh(self) -> None:
        key = (self.voxels.n, self.voxels.version)
        if self._key != key:
            self._items = segment_instances(self.voxels, self._table(), self.config)
            self._labels = None
            self._key = key

    def table(self):
        """The table the instances stand on (the map's fit; None without one)."""
        return self._table()

    def restore(self, labels: np.ndarray) -> None:
        """Take a saved segmentation (per voxel row: its instance id, -1 for none) for the
        current voxels instead of segmenting them again."""
        labels = np.asarray(labels, np.int64)
        if labels.shape != (self.voxels.n,):
            raise ConfigError(
                f"saved instance labels have {labels.shape} entries, the map {self.voxels.n} voxels"
            )
        if labels.size and labels.min() < -1:
            raise ConfigError(f"saved instance labels must be >= -1, got {int(labels.min())}")
        self._items = instances_from_labels(self.voxels, labels)
        self._labels = labels
        self._key = (self.voxels.n, self.voxels.version)

    @property
    def items(self) -> list[ObjectInstance]:
        self._refresh()
        return self._items

    def __len__(self) -> int:
        return len(self.items)

    def __iter__(self):
        return iter(self.items)

    def labels(self) -> np.ndarray:
        """(n,) per voxel row: the id of its instance, -1 for none."""
        self._refresh()
        if self._labels is None:
            out = np.full(self.voxels.n, -1, np.int64)
            for inst in self._items:
                out[inst.rows] = inst.id
            self._labels = out
        return self._labels


def instances_from_labels(voxels: VoxelMap, labels: np.ndarray) -> list[ObjectInstance]:
    """The instances a labelling of the voxel rows (0..k-1, -1 for none) describes."""
    state = voxels.state()
    centers = voxels.centers
    h = voxels.grid.voxel_size / 2
    out = []
    for k in range(int(labels.max(initial=-1)) + 1):
        rows = np.nonzero(labels == k)[0]
        if not len(rows):
            raise ConfigError(f"saved instance labels skip instance {k}")
        pts = int(state["counts"][rows].sum())
        e = state["feature_sums"][rows].sum(axis=0) / max(pts, 1)
        e = e / max(float(np.linalg.norm(e)), 1e-12)
        c = state["color_sums"][rows].sum(axis=0) / max(pts, 1)
        ctr = centers[rows]
        counts = state["counts"][rows].astype(np.float64)
        vox_rgb = state["color_sums"][rows] / np.maximum(counts[:, None], 1)
        # Shares of its surface (voxels), not of its pixels: a domino's dark faces return
        # fewer pixels than its bright edges, yet are most of what it looks like.
        palette, share = colour_palette(rgb_to_lab(vox_rgb), np.ones(len(rows)))
        out.append(
            ObjectInstance(
                k,
                rows,
                ctr.mean(axis=0),
                ctr.min(axis=0) - h,
                ctr.max(axis=0) + h,
                c,
                rgb_to_lab(c),
                e.astype(np.float32),
                pts,
                palette,
                share,
            )
        )
    return out


#: Two colour clusters of an instance closer than this CIELAB ΔE (:func:`delta_e`) are one
#: colour under shading, not two colours.
PALETTE_MIN_DELTA_E = 25.0


def colour_palette(lab: np.ndarray, weights: np.ndarray, iters: int = 10):
    """((k, 3) CIELAB, (k,) shares): the distinct colours of an object's voxels (``lab``,
    (n, 3), weighted by ``weights``): two clusters (weighted 2-means in the :func:`delta_e`
    metric, started from the darker and the lighter half) when they lie at least
    :data:`PALETTE_MIN_DELTA_E` apart — a domino's black faces and white edges, a soccer
    ball's panels — and none otherwise (one colour, shaded: the mean says it)."""
    lab = np.asarray(lab, np.float64).reshape(-1, 3)
    w = np.asarray(weights, np.float64).reshape(-1)
    if len(lab) < 2 or not w.sum() > 0:
        return np.zeros((0, 3)), np.zeros(0)
    scale = np.array([0.5, 1.0, 1.0])  # the metric of delta_e
    x = lab * scale
    dark = lab[:, 0] <= np.median(lab[:, 0])
    if dark.all():
        return np.zeros((0, 3)), np.zeros(0)
    c = np.stack(
        [np.average(x[dark], 0, w[dark] + 1e-12), np.average(x[~dark], 0, w[~dark] + 1e-12)]
    )
    assign = np.zeros(len(x), np.int64)
    for _ in range(iters):
        assign = ((x[:, None] - c[None]) ** 2).sum(-1).argmin(1)
        for j in range(2):
            m = assign == j
            if m.any() and w[m].sum() > 0:
                c[j] = np.average(x[m], 0, w[m])
    share = np.array([w[assign == j].sum() for j in range(2)]) / w.sum()
    centres = c / scale
    if float(delta_e(centres[0], centres[1])) < PALETTE_MIN_DELTA_E or share.min() == 0:
        return np.zeros((0, 3)), np.zeros(0)
    order = np.argsort(-share, kind="stable")
    return centres[order], share[order]
