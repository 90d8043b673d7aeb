"""Small synthetic maps for the module tests: real MiniLM text embeddings, made-up geometry."""

import functools

import numpy as np

from tabletop.grid import VoxelGrid
from tabletop.mapping.voxel_map import VoxelMap

GRID = VoxelGrid(lower=(0.0, -0.3, 0.0), upper=(0.6, 0.3, 0.2), voxel_size=0.01)


@functools.cache
def text_encoder():
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder

    return MiniLMTextEncoder()


def box_points(lo, hi, step=0.005) -> np.ndarray:
    """(P, 3) [m] points filling the box [lo, hi]."""
    axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def labelled_voxels(boxes: dict[str, tuple]) -> VoxelMap:
    """A voxel map whose voxels carry the text embedding of their box's label (``boxes``:
    label -> (lo, hi) [m]); the table top is a slab labelled "table"."""
    return coloured_voxels({k: (lo, hi, (128, 128, 128)) for k, (lo, hi) in boxes.items()})


def judge_at(threshold: float):
    """A calibration stand-in: found when the margin reaches ``threshold``."""
    return lambda modality, margin: (float(np.clip(margin, 0, 1)), margin >= threshold)


def coloured_voxels(boxes: dict[str, tuple]) -> VoxelMap:
    """Like :func:`labelled_voxels`, each box ``label -> (lo, hi, rgb)`` with its own colour
    (the table is mid grey)."""
    text = text_encoder()
    labels = ["table", *boxes]
    table = text.encode_text(labels)
    vm = VoxelMap(GRID, text.dim)
    pts = [box_points((0.0, -0.3, 0.0), (0.6, 0.3, 0.01), 0.01)]
    idx = [np.zeros(len(pts[0]), np.int64)]
    cols = [np.full((len(pts[0]), 3), 128, np.uint8)]
    for i, (lo, hi, rgb) in enumerate(boxes.values(), start=1):
        pts.append(box_points(lo, hi))
        idx.append(np.full(len(pts[-1]), i, np.int64))
        cols.append(np.tile(np.array(rgb, np.uint8), (len(pts[-1]), 1)))
    vm.integrate(
        np.concatenate(pts), table, np.concatenate(cols), feature_index=np.concatenate(idx)
    )
    return vm
