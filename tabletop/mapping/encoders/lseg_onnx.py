"""The default image encoder's network on onnxruntime: the same weights, a faster runtime.

:class:`~tabletop.mapping.encoders.lseg.LSegEncoder` runs its network here when it can. The
graph is exported once from the shipped torch weights (``torch.onnx.export``) for one input
size and kept in the user's cache directory (:func:`cache_dir`), named by the weights file's
SHA-256, the input size and :data:`GRAPH_VERSION`: no second copy of the weights is committed,
and a retrained file gets its own graph. The file is written atomically; a cached graph that
does not load is exported again.

The exported graph takes the (H, W, 3) uint8 image and returns the (1, H/s, W/s, dim)
float32 L2-normalised embeddings, so pre- and post-processing run inside onnxruntime too. It
differs from the torch module only in form:

- TensorFlow-style ``SAME`` padding of the stride-2 convolutions, which torch does with a
  separate ``F.pad``, becomes the convolutions' own (asymmetric) ``pads``;
- the input normalisation is one multiply-add per channel plane;
- the output is channels-last straight from the last convolution (onnxruntime writes it so
  in the step that leaves its blocked layout), L2-normalised over that last axis.

Every export is checked against the torch module on a fixed random image and used only when
the two agree to :data:`EXPORT_TOLERANCE`; anything that goes wrong (no onnxruntime, an export
error, an unwritable cache) makes :func:`session` return None, and the encoder runs on torch.

``int8=True`` (``LSegEncoder(backend="int8")``, not the default: the embeddings change)
quantises that graph statically (onnxruntime's ``quantize_static``: int8 weights per output
channel, uint8 activations) with activation ranges measured on :data:`CALIBRATION_LAYOUTS`,
rendered training layouts (never held-out ones; rendering needs the simulator, once), and
keeps it in the cache beside the float graph. Input scaling and the bilinear upsampling stay
in float.

Measured on one thread, 320x240 renders, the two runtimes alternating in one process on a
shared 2-core AMD EPYC: median 48 ms per frame with torch, 27 ms with onnxruntime (the
per-frame ratio 0.56), the same embeddings to 1e-6.
"""

from __future__ import annotations

import functools
import hashlib
import io
import logging
import os
import threading
import warnings
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError
from tabletop.paths import DATA_DIR

__all__ = [
    "CALIBRATION_LAYOUTS",
    "CALIBRATION_PATH",
    "EXPORT_TOLERANCE",
    "GRAPH_VERSION",
    "INT8_VERSION",
    "cache_dir",
    "export_graph",
    "graph_path",
    "session",
    "weights_digest",
]

log = logging.getLogger(__name__)

GRAPH_VERSION = 2
"""Bumped whenever :func:`export_graph` changes what it writes: old cache files are left
unread."""

EXPORT_TOLERANCE = 1e-4
"""Largest difference from the torch module's embeddings an exported graph may show."""

INT8_VERSION = 1
"""Bumped whenever the int8 graph's calibration or quantisation changes."""

CALIBRATION_LAYOUTS = (0, 1, 2, 3)
"""Layout seeds (``tabletop.train.vision`` training seeds ``0 * 100_000 + i``) rendered, two
views each, to measure the int8 graph's activation ranges."""
CALIBRATION_PATH = DATA_DIR / "weights" / "lseg_int8_calibration.npz"
"""Those renders, committed (``tools/build_int8_calibration.py``)."""

_OPSET = 17
_lock = threading.Lock()


def cache_dir() -> Path:
    """Where exported graphs are kept: ``$XDG_CACHE_HOME/tabletop``, else
    ``~/.cache/tabletop``."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "tabletop"


@functools.cache
def weights_digest(path: str) -> str:
    """SHA-256 of a weights file (hex; read once per path and process)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def graph_path(weights: str | Path, height: int, width: int, int8: bool = False) -> Path:
    """The cache file of the graph of ``weights`` for (height, width) images (``int8``: its
    quantised graph)."""
    digest = weights_digest(str(Path(weights).resolve()))
    tail = f"-int8-c{INT8_VERSION}" if int8 else ""
    return cache_dir() / f"lseg-{digest[:32]}-{height}x{width}-v{GRAPH_VERSION}{tail}.onnx"


def _export_module(net, mean, std):
    """A torch module computing what the encoder returns, from the uint8 image."""
    import torch

    class _Export(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.net = net
            m, sd = torch.tensor(mean, dtype=torch.float32), torch.tensor(std, dtype=torch.float32)
            # (x / 255 - m) / s as one multiply-add per channel plane
            self.register_buffer("scale", (1.0 / (255.0 * sd)).view(1, 3, 1, 1))
            self.register_buffer("shift", (-m / sd).view(1, 3, 1, 1))

        def forward(self, rgb):
            x = rgb.permute(2, 0, 1).unsqueeze(0).float() * self.scale + self.shift
            # channels-last straight from the last convolution (no Gather of the batch axis in
            # between), so that onnxruntime's layout passes can drop the transposes
            y = self.net.proj(self.net.features(x)).permute(0, 2, 3, 1)
            # (1, h, w, dim): the caller drops the batch axis (a view; a Reshape here copies)
            return y / torch.linalg.vector_norm(y, dim=-1, keepdim=True).clamp_min(1e-12)

    return _Export().eval()


def _same_pads(net, rgb) -> list[list[int]]:
    """The (top, left, bottom, right) zero padding of every dynamically padded convolution of
    ``net`` on an image of ``rgb``'s size, in the order the forward pass applies them."""
    import math

    import torch

    pads = []

    def hook(module, args):
        if getattr(module, "_pad_dynamic", False):
            k, s = module.kernel_size[0], module.stride[0]
            h, w = args[0].shape[-2:]
            ph = max((math.ceil(h / s) - 1) * s + k - h, 0)
            pw = max((math.ceil(w / s) - 1) * s + k - w, 0)
            pads.append([ph // 2, pw // 2, ph - ph // 2, pw - pw // 2])

    handles = [m.register_forward_pre_hook(hook) for m in net.modules()]
    try:
        with torch.inference_mode():
            x = torch.zeros((1, 3, *rgb.shape[:2]))
            net.proj(net.features(x))
    finally:
        for h in handles:
            h.remove()
    return pads


def _fold_pads(model, pads: list[list[int]]) -> None:
    """Merge each ``Pad`` node (in graph order, one per entry of ``pads``) into the
    convolution it feeds. Leaves the model as it is when the nodes do not line up."""
    from onnx import helper

    graph = model.graph
    pad_nodes = [n for n in graph.node if n.op_type == "Pad"]
    consumers: dict[str, list] = {}
    for n in graph.node:
        for i in n.input:
            consumers.setdefault(i, []).append(n)
    if len(pad_nodes) != len(pads):
        return
    plan = []
    for node, p in zip(pad_nodes, pads, strict=True):
        users = consumers.get(node.output[0], [])
        modes = [a.s for a in node.attribute if a.name == "mode"]
        if len(users) != 1 or users[0].op_type != "Conv" or modes not in ([], [b"constant"]):
            return
        if len(node.input) > 2 and node.input[2]:  # a constant value other than the default 0
            return
        conv = users[0]
        for a in conv.attribute:
            if (a.name == "pads" and any(a.ints)) or (a.name == "auto_pad" and a.s != b"NOTSET"):
                return
        plan.append((node, conv, p))
    for node, conv, p in plan:
        kept = [a for a in conv.attribute if a.name != "pads"]
        del conv.attribute[:]
        conv.attribute.extend([*kept, helper.make_attribute("pads", list(p))])
        conv.input[0] = node.input[0]
        graph.node.remove(node)
    _prune(graph)


def _prune(graph) -> None:
    """Drop nodes whose outputs nothing reads (the pads' shape arithmetic)."""
    outputs = {o.name for o in graph.output}
    while True:
        used = outputs | {i for n in graph.node for i in n.input}
        dead = [n for n in graph.node if not any(o in used for o in n.output)]
        if not dead:
            return
        for n in dead:
            graph.node.remove(n)


def export_graph(net, mean, std, height: int, width: int) -> bytes:
    """The serialised ONNX graph of ``net`` (with the input normalisation ``mean``, ``std``)
    for (height, width, 3) uint8 images."""
    import onnx
    import torch

    rgb = np.zeros((height, width, 3), np.uint8)
    buf = io.BytesIO()
    with warnings.catch_warnings(), torch.inference_mode(False), torch.no_grad():
        warnings.simplefilter("ignore")
        torch.onnx.export(
            _export_module(net, mean, std),
            (torch.from_numpy(rgb),),
            buf,
            input_names=["rgb"],
            output_names=["embeddings"],
            opset_version=_OPSET,
            dynamo=False,
        )
    model = onnx.load_from_string(buf.getvalue())
    _fold_pads(model, _same_pads(net, rgb))
    onnx.checker.check_model(model)
    return model.SerializeToString()


def _check_image(height: int, width: int) -> np.ndarray:
    """The fixed image an export is checked on: smooth colour fields with noise."""
    rng = np.random.default_rng(1234)
    yy, xx = np.mgrid[0:height, 0:width] / max(height, width)
    base = np.stack([np.sin(6 * xx), np.cos(5 * yy), np.sin(4 * (xx + yy))], -1) * 80 + 128
    return np.clip(base + rng.normal(0, 20, base.shape), 0, 255).astype(np.uint8)


def _torch_embeddings(net, mean, std, rgb) -> np.ndarray:
    from tabletop.mapping.encoders.base import preprocess, torch_threads

    with torch_threads(1):
        emb = net(preprocess(rgb, mean, std))[0]
    return emb.permute(1, 2, 0).numpy()


def _new_session(data: bytes | str, num_threads: int | None):
    import onnxruntime as ort

    opts = ort.SessionOptions()
    opts.intra_op_num_threads = int(num_threads) if num_threads else 0
    opts.inter_op_num_threads = 1
    opts.log_severity_level = 3
    return ort.InferenceSession(data, opts, providers=["CPUExecutionProvider"])


def _agrees(sess, net, mean, std, height: int, width: int) -> float:
    rgb = _check_image(height, width)
    want = _torch_embeddings(net, mean, std, rgb)
    got = sess.run(None, {"rgb": rgb})[0][0]
    if got.shape != want.shape:
        return float("inf")
    return float(np.abs(got - want).max())


def _float_graph(net, weights: str, mean, std, height: int, width: int) -> bytes:
    """The float graph's bytes, from the cache when it holds a good one, else exported (and
    then checked against torch and kept)."""
    path = graph_path(weights, height, width)
    if path.is_file():
        try:
            data = path.read_bytes()
            if _agrees(_new_session(data, 1), net, mean, std, height, width) <= EXPORT_TOLERANCE:
                return data
            log.warning("cached graph %s disagrees with the weights; exporting again", path)
        except Exception as e:  # a truncated or foreign file: export again
            log.warning("cached graph %s is unreadable (%s); exporting again", path, e)
    data = export_graph(net, mean, std, height, width)
    diff = _agrees(_new_session(data, 1), net, mean, std, height, width)
    if diff > EXPORT_TOLERANCE:
        raise RuntimeError(f"the exported graph differs from the torch network by {diff:.2e}")
    _keep(path, data)
    return data


def _keep(path: Path, data: bytes) -> None:
    try:
        from tabletop.atomic import atomic_path

        with atomic_path(path) as tmp:
            tmp.write_bytes(data)
    except Exception as e:  # a read-only home: the session still runs, exported per process
        log.warning("could not keep the exported graph at %s: %s", path, e)


def calibration_frames(height: int, width: int) -> np.ndarray:
    """(N, height, width, 3) uint8 renders of :data:`CALIBRATION_LAYOUTS`, read from
    :data:`CALIBRATION_PATH` (written by ``tools/build_int8_calibration.py``: the map layer
    does not render), resampled to the size by nearest pixel when the renders have another."""
    try:
        with np.load(CALIBRATION_PATH, allow_pickle=False) as z:
            rgbs = np.asarray(z["rgb"], np.uint8)
    except (OSError, KeyError, ValueError) as e:
        raise AssetError(
            f"the int8 calibration frames {CALIBRATION_PATH} are unreadable: {e}"
        ) from None
    if rgbs.ndim != 4 or rgbs.shape[-1] != 3 or not len(rgbs):
        raise AssetError(f"{CALIBRATION_PATH}: expected (N, H, W, 3) frames, got {rgbs.shape}")
    H, W = rgbs.shape[1:3]
    if (H, W) != (height, width):
        rows = (np.arange(height) * H // height)[:, None]
        cols = (np.arange(width) * W // width)[None, :]
        rgbs = rgbs[:, rows, cols]
    return np.ascontiguousarray(rgbs)


def quantize_graph(data: bytes, frames: np.ndarray) -> bytes:
    """The int8 graph of a float graph's bytes, activation ranges measured on ``frames``."""
    import tempfile

    import onnx
    from onnxruntime.quantization import (
        CalibrationDataReader,
        QuantFormat,
        QuantType,
        quantize_static,
    )

    model = onnx.load_from_string(data)
    first_conv = next(i for i, n in enumerate(model.graph.node) if n.op_type == "Conv")
    # the input scaling before the first convolution and the upsampling stay float: quantised,
    # onnxruntime runs them slower than in float, and they cost little accuracy either way
    keep_float = [
        n.name
        for i, n in enumerate(model.graph.node)
        if n.op_type == "Resize" or (i < first_conv and n.op_type in ("Mul", "Add"))
    ]

    class _Frames(CalibrationDataReader):
        def __init__(self):
            self._it = iter(frames)

        def get_next(self):
            f = next(self._it, None)
            return None if f is None else {"rgb": f}

    with tempfile.TemporaryDirectory(prefix="tabletop-int8-") as tmp:
        src, dst = Path(tmp) / "float.onnx", Path(tmp) / "int8.onnx"
        src.write_bytes(data)
        quantize_static(
            str(src),
            str(dst),
            _Frames(),
            quant_format=QuantFormat.QOperator,
            per_channel=True,
            activation_type=QuantType.QUInt8,
            weight_type=QuantType.QInt8,
            nodes_to_exclude=keep_float,
        )
        return dst.read_bytes()


def _build_session(net, weights: str, mean, std, height: int, width: int, num_threads, int8):
    if not int8:
        return _new_session(_float_graph(net, weights, mean, std, height, width), num_threads)
    path = graph_path(weights, height, width, int8=True)
    if path.is_file():
        try:
            return _new_session(str(path), num_threads)
        except Exception as e:
            log.warning("cached int8 graph %s is unreadable (%s); quantising again", path, e)
    data = quantize_graph(
        _float_graph(net, weights, mean, std, height, width), calibration_frames(height, width)
    )
    sess = _new_session(data, num_threads)
    _keep(path, data)
    return sess


_sessions: dict[tuple, object] = {}


def session(
    net, weights: str | Path, mean, std, height: int, width: int, num_threads=1, int8=False
):
    """An onnxruntime session computing ``net``'s embeddings of (height, width, 3) uint8
    images (``net`` loaded from ``weights`` with the input normalisation ``mean``, ``std``;
    ``num_threads`` intra-op threads, None: onnxruntime's default; ``int8``: the quantised
    graph), or None when onnxruntime cannot run it: the reason is logged once and the caller
    falls back. One try per weights file, size, thread count and precision in a process."""
    key = (id(net), str(weights), int(height), int(width), num_threads, bool(int8))
    with _lock:
        if key not in _sessions:
            try:
                w = str(Path(weights).resolve())
                _sessions[key] = _build_session(
                    net, w, tuple(mean), tuple(std), int(height), int(width), num_threads, int8
                )
            except Exception as e:
                _warn_once(f"{type(e).__name__}: {e}")
                _sessions[key] = None
        return _sessions[key]


@functools.cache
def _warn_once(reason: str) -> None:
    log.warning("the image encoder cannot use this onnxruntime graph (%s)", reason)
