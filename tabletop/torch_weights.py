"""Loading a torch weights file safely, with one wording for a file that is not one.

``torch.load(..., weights_only=True)`` refuses a file that is not a checkpoint of tensors with
advice to load it with ``weights_only=False``, which would run the file's code. The user is
told instead that the file is not a weights file of the expected format, naming it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["load_torch_weights", "weights_load_problem"]


def weights_load_problem(path: str | Path, error: BaseException) -> str:
    """Why ``path`` could not be loaded as weights, in words, never suggesting unsafe loading."""
    text = str(error)
    kind = type(error).__name__
    if "weights_only" in text or "Weights only" in text or kind == "UnpicklingError":
        return (
            f"{str(path)!r} is not a weights file of the expected format (a torch checkpoint "
            "of tensors and plain values); it was not loaded"
        )
    first = text.strip().splitlines()[0] if text.strip() else kind
    return f"{str(path)!r} is not a weights file of the expected format ({first})"


def load_torch_weights(path: str | Path, error: type[Exception], hint: str = "") -> Any:
    """``torch.load(path, weights_only=True)`` on the CPU; a file that is not a weights file
    raises ``error`` naming the path (and ``hint``: what to give instead)."""
    import torch

    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # torch raises many types for a damaged or foreign file
        raise error(weights_load_problem(path, e) + (f"; {hint}" if hint else "")) from None
