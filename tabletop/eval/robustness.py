"""Robustness: the same task files run clean and under each of a set of sensor imperfections,
and the drop in success per goal type.

```python
from tabletop.eval.robustness import run_robustness

res = run_robustness("default", encoders="default", out_dir="out/robustness")
print(res.to_markdown())          # clean vs each condition, drop in points per goal type
```

Every condition starts from the same cached clean scan: the noise
(:class:`~tabletop.sim.noise.NoiseConfig`, seeded) is applied to the recording, and the map is
built from the noisy recording; the robot then moves in the true (clean) simulator, so a target
that the noise displaced is a miss, as it would be on a real arm.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from tabletop.errors import ConfigError
from tabletop.eval.report import EvalResult
from tabletop.eval.results import dumps

__all__ = ["CONDITIONS", "MAX_DROP_POINTS", "RobustnessResult", "run_robustness"]

CONDITIONS: dict[str, dict] = {
    "pose": {"pose_translation_m": 0.005, "pose_rotation_rad": math.radians(1.0)},
    "depth": {"depth_relative": 0.004, "depth_dropout": 0.05},
    "drop-frames": {"drop_frames": 0.2},
    "extrinsic": {"extrinsic_translation_m": 0.005, "extrinsic_rotation_rad": math.radians(1.0)},
    "clock": {"clock_offset_s": 0.05},
}
"""The sensor imperfections of ``tabletop eval --robustness`` (noise seed 0 each):

- ``pose``: 5 mm / 1° Gaussian noise on every recorded end-effector pose;
- ``depth``: stereo-like depth noise, std 0.004·z² (a 5 cm baseline, a 380 px focal length and
  a 0.08 px disparity error: a D435-class camera) and 5 % of the valid pixels dropped;
- ``drop-frames``: 20 % of the frames lost;
- ``extrinsic``: the wrist camera's calibration off by 5 mm and 1° (one fixed error);
- ``clock``: the audio clock 50 ms late against the frames."""

MAX_DROP_POINTS = 10.0
"""The largest drop [percentage points] below clean that a condition may cost a goal type."""


def _signed(points: float) -> str:
    """``+5``, ``-12``, ``0`` (never ``-0``)."""
    v = round(points)
    return f"{v:+d}" if v else "0"


def _noise_description(noise: dict) -> str:
    parts = []
    for k, v in noise.items():
        if k.endswith("_rad"):
            parts.append(f"{k[:-4]} {math.degrees(v):.1f}°")
        elif k.endswith("_m"):
            parts.append(f"{k[:-2]} {v * 1000:.0f} mm")
        elif k.endswith("_s"):
            parts.append(f"{k[:-2]} {v * 1000:.0f} ms")
        else:
            parts.append(f"{k} {v:g}")
    return ", ".join(parts)


@dataclass
class RobustnessResult:
    """One :class:`EvalResult` per condition (``clean`` first) over the same task files."""

    results: dict[str, EvalResult]
    conditions: dict[str, dict]
    wall_s: float = 0.0
    out_dir: Path | None = None
    drops: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.drops = self._drops()

    def _rates(self, name: str, encoders: str) -> dict:
        res = self.results[name]
        run = next(r for r in res.runs if r.encoders == encoders)
        if not run.available:
            return {}
        s = run.summary()
        rates = {t: v for t, v in s["by_type"].items()}
        rates["all"] = s["all"]
        return rates

    def _drops(self) -> dict:
        """encoders -> condition -> goal type -> {clean, noisy, drop} (drop in points)."""
        out: dict = {}
        clean = self.results["clean"]
        for run in clean.runs:
            if not run.available:
                continue
            base = self._rates("clean", run.encoders)
            per: dict = {}
            for name in self.conditions:
                noisy = self._rates(name, run.encoders)
                rows = {}
                for t, v in base.items():
                    w = noisy.get(t)
                    if v["success_rate"] is None or w is None or w["success_rate"] is None:
                        continue
                    rows[t] = {
                        "clean": v["success_rate"],
                        "noisy": w["success_rate"],
                        "drop_points": 100.0 * (v["success_rate"] - w["success_rate"]),
                        "contacts": w["contacts"],
                    }
                per[name] = rows
            out[run.encoders] = per
        return out

    @property
    def worst_drop(self) -> float:
        """The largest drop [points] of any goal type under any condition."""
        return max(
            (
                r["drop_points"]
                for per in self.drops.values()
                for c in per.values()
                for r in c.values()
            ),
            default=0.0,
        )

    @property
    def contacts(self) -> int:
        return sum(
            r["contacts"]
            for per in self.drops.values()
            for c in per.values()
            for t, r in c.items()
            if t == "all"
        )

    def table_markdown(self) -> str:
        names = list(self.conditions)
        lines = []
        for enc, per in self.drops.items():
            head = "| goal type | clean % | " + " | ".join(f"{n} % (drop)" for n in names) + " |"
            lines += [f"**{enc}** encoders", "", head, "|" + "---|" * (len(names) + 2)]
            base = self._rates("clean", enc)
            for t, v in base.items():
                if v["success_rate"] is None:
                    continue
                cells = []
                for n in names:
                    r = per[n].get(t)
                    if r is None:
                        cells.append("–")
                    else:
                        cells.append(f"{100 * r['noisy']:.0f} ({_signed(-r['drop_points'])})")
                name = f"**{t}**" if t == "all" else t
                lines.append(
                    f"| {name} | {100 * v['success_rate']:.0f} ({v['successes']}/"
                    f"{v['attempted']}) | " + " | ".join(cells) + " |"
                )
            contacts = " | ".join(str(per[n].get("all", {}).get("contacts", "–")) for n in names)
            lines += [f"| contacts | {base['all']['contacts']} | {contacts} |", ""]
        return "\n".join(lines)

    def to_markdown(self) -> str:
        out = ["# Robustness to sensor imperfections", ""]
        out.append(
            "The same task files, clean and under each condition; cells: success % and, in "
            "brackets, the change in points against clean (negative: worse). The noise is "
            "applied to the clean scan (seed 0) before mapping; the arm moves in the true "
            "simulator. "
            f"Target: no goal type more than {MAX_DROP_POINTS:.0f} points below clean, 0 "
            "contacts. The **oracle** encoders are the simulator's labels (an upper bound); "
            "**default** the embedded learned encoders."
        )
        out += ["", "Conditions:", ""]
        for n, c in self.conditions.items():
            out.append(f"- `{n}`: {_noise_description(c)}")
        files = next(iter(self.results.values())).task_files
        out += ["", f"Task files: {', '.join(f'`{p}`' for p in files)}", ""]
        out += [self.table_markdown(), ""]
        out.append(
            f"Worst drop: {self.worst_drop:.0f} points; contacts under noise: {self.contacts}; "
            f"{self.wall_s:.0f} s in all."
        )
        return "\n".join(out)

    def to_json(self) -> dict:
        return {
            "conditions": self.conditions,
            "drops": self.drops,
            "worst_drop_points": self.worst_drop,
            "contacts": self.contacts,
            "max_drop_points": MAX_DROP_POINTS,
            "wall_s": round(self.wall_s, 1),
            "results": {n: r.to_json() for n, r in self.results.items()},
        }

    def write(self, out_dir: str | Path) -> Path:
        """``robustness.md``, ``robustness.json``, and each condition's report in its own
        directory under ``out_dir``."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        self.out_dir = out
        (out / "robustness.json").write_text(dumps(self.to_json()))
        path = out / "robustness.md"
        path.write_text(self.to_markdown())
        return path


def run_robustness(
    tasks,
    encoders: str | Sequence[str] = "default",
    out_dir: str | Path | None = None,
    progress=None,
    cache_dir=None,
    conditions: Sequence[str] | None = None,
    on_condition=None,
    workers: int | None = None,
    ray: str | None = None,
) -> RobustnessResult:
    """Run ``tasks`` clean and under each of ``conditions`` (names in :data:`CONDITIONS`; all
    by default) with ``encoders``. ``on_condition(name)`` is called as each begins.
    ``workers``, ``ray``: each condition's units of work in parallel (:func:`run_eval`)."""
    from tabletop.eval.harness import DEFAULT_CACHE_DIR
    from tabletop.eval.runner import collect_task_files, run_eval

    names = list(CONDITIONS) if conditions is None else list(conditions)
    bad = [n for n in names if n not in CONDITIONS]
    if bad or not names:
        raise ConfigError(f"unknown robustness conditions {bad}; valid: {list(CONDITIONS)}")
    files = collect_task_files(tasks)  # a bad task file fails before any scan
    cache = DEFAULT_CACHE_DIR if cache_dir is None else cache_dir
    out = Path(out_dir) if out_dir is not None else None
    t0 = time.perf_counter()
    results: dict[str, EvalResult] = {}
    for name in ["clean", *names]:
        if on_condition is not None:
            on_condition(name)
        noise = {} if name == "clean" else {"seed": 0, **CONDITIONS[name]}
        results[name] = run_eval(
            files,
            encoders=encoders,
            out_dir=None if out is None else out / name,
            progress=progress,
            cache_dir=cache,
            noise=noise,
            workers=workers,
            ray=ray,
        )
    res = RobustnessResult(results, {n: CONDITIONS[n] for n in names}, time.perf_counter() - t0)
    if out is not None:
        res.write(out)
    return res
