"""The evaluation report: the table (Markdown, JSON) and the pictures a person looks at.

Pictures per task file: the scene from above (map colours) with the ground-truth boxes, where
each sound was heard, each goal's truth and where the TCP ended; the heatmaps of a few goals
(primary, auxiliary and fused, over the map's colours, in JET); the query images of image goals.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from tabletop.eval.results import RECALL_RADII_M, SUCCESS_RADIUS_M, EncoderRun, dumps
from tabletop.sim.ground_truth import GroundTruth

__all__ = ["EvalResult", "write_task_figures"]

_SCALE = 6
_GREEN, _RED, _BLUE, _YELLOW, _WHITE = (
    (60, 200, 60),
    (40, 40, 230),
    (230, 140, 40),
    (0, 220, 240),
    (255, 255, 255),
)


def _pct(v) -> str:
    return "–" if v is None else f"{100 * v:.0f}"


def _cm(v) -> str:
    return "–" if v is None else f"{100 * v:.1f}"


@dataclass
class EvalResult:
    """Rows (one :class:`EncoderRun` per encoder set) over the same task files."""

    task_files: list[str]
    runs: list[EncoderRun]
    out_dir: Path | None = None
    reader: str = ""
    """The reader that read every goal's words (:data:`tabletop.reader.READERS`)."""

    @property
    def report_path(self) -> Path | None:
        return self.out_dir / "report.md" if self.out_dir is not None else None

    def to_json(self) -> dict:
        """The first encoder set's summary at the top level (``encoders``, ``by_type.<type>.
        success_rate``, ``contacts``, ``in_a_row``, ...), every set's in ``rows``, every goal
        in ``goals`` (per row)."""
        rows = []
        for r in self.runs:
            s = r.summary()
            s["tasks"] = [
                {
                    "task": t.task_path,
                    "scene": t.scene,
                    "scan_s": round(t.scan_s, 1),
                    "map_s": round(t.map_s, 1),
                    "cached": t.cached,
                    "figures": t.figures,
                    "map_file": t.map_path,
                    "recording_dir": t.recording_path,
                    "driver": t.driver,
                    **({"tracking": t.tracking} if t.tracking else {}),
                    "goals": [g.to_json() for g in t.goals],
                }
                for t in r.tasks
            ]
            rows.append(s)
        top = {k: v for k, v in rows[0].items() if k != "tasks"}
        return {
            **top,
            "task_files": self.task_files,
            "success_radius_m": self.success_radius,
            "robot": self.robot,
            "reader": self.reader,
            "report": str(self.report_path) if self.report_path else None,
            "rows": rows,
        }

    @property
    def robot(self) -> str:
        """The robot the task files are for (:mod:`tabletop.embodiments`; "arm" when no task
        ran), or "mixed"."""
        kinds = {t.robot for r in self.runs for t in r.tasks}
        return kinds.pop() if len(kinds) == 1 else ("mixed" if kinds else "arm")

    @property
    def mobile(self) -> bool:
        """Whether the task files are a robot's that works in rooms (success within a radius
        on the floor; its embodiment's workspace is a room)."""
        from tabletop.embodiments import EMBODIMENTS

        body = EMBODIMENTS.get(self.robot)
        return body is not None and body.workspace == "room"

    @property
    def success_radius(self) -> float:
        """[m] the task files' success radius (the arm's 10 cm when no task ran)."""
        radii = {t.success_radius for r in self.runs for t in r.tasks}
        return max(radii) if radii else SUCCESS_RADIUS_M

    def table_markdown(self) -> str:
        """The per-type table: one row per goal type and encoder set."""
        if self.mobile:
            return self._mobile_table()
        head = (
            "| goal type | encoders | goals | success % | "
            + " | ".join(f"R@{int(r * 100)} cm %" for r in RECALL_RADII_M)
            + " | TCP error cm | target error cm | contacts | s / goal |"
        )
        lines = [head, "|" + "---|" * (head.count("|") - 1)]
        types = []
        for r in self.runs:
            for t in r.summary()["by_type"]:
                if t not in types:
                    types.append(t)
        for t in [*types, "all"]:
            for r in self.runs:
                if not r.available:
                    if t != "all":
                        continue
                    lines.append(f"| {t} | {r.label} | unavailable: {r.reason} |" + " |" * 9)
                    continue
                s = r.summary()
                v = s["all"] if t == "all" else s["by_type"].get(t)
                if v is None:
                    continue
                name = f"**{t}**" if t == "all" else t
                if v["attempted"] == 0:
                    lines.append(
                        f"| {name} | {r.label} | {v['goals']} | unavailable: "
                        f"{v.get('unavailable_reason', '')} |" + " |" * 8
                    )
                    continue
                goals = f"{v['attempted']}" + (
                    f" (+{v['unavailable']} unavailable)" if v["unavailable"] else ""
                )
                rec = " | ".join(_pct(x) for x in v["recall_at"].values())
                lines.append(
                    f"| {name} | {r.label} | {goals} | {_pct(v['success_rate'])} "
                    f"({v['successes']}/{v['attempted']}) | {rec} | {_cm(v['mean_error_m'])} | "
                    f"{_cm(v['mean_target_error_m'])} | {v['contacts']} | "
                    f"{v['time_per_goal_s']:.1f} |"
                )
        return "\n".join(lines)

    def _mobile_table(self) -> str:
        """A mobile base's table: success within the radius on the floor, the base's and the
        target's distance to the truth [m], collisions."""
        r_m = self.success_radius
        head = (
            f"| goal type | encoders | goals | success % (within {r_m:g} m) | base error m | "
            "target error m | collisions | s / goal |"
        )
        lines = [head, "|" + "---|" * (head.count("|") - 1)]
        types = []
        for r in self.runs:
            for t in r.summary()["by_type"]:
                if t not in types:
                    types.append(t)
        for t in [*types, "all"]:
            for r in self.runs:
                if not r.available:
                    if t == "all":
                        lines.append(f"| {t} | {r.label} | unavailable: {r.reason} |" + " |" * 5)
                    continue
                s = r.summary()
                v = s["all"] if t == "all" else s["by_type"].get(t)
                if v is None or v["attempted"] == 0:
                    continue
                name = f"**{t}**" if t == "all" else t
                err = "–" if v["mean_error_m"] is None else f"{v['mean_error_m']:.2f}"
                terr = (
                    "–" if v["mean_target_error_m"] is None else f"{v['mean_target_error_m']:.2f}"
                )
                lines.append(
                    f"| {name} | {r.label} | {v['attempted']} | {_pct(v['success_rate'])} "
                    f"({v['successes']}/{v['attempted']}) | {err} | {terr} | {v['contacts']} | "
                    f"{v['time_per_goal_s']:.1f} |"
                )
        return "\n".join(lines)

    def reach_markdown(self) -> str:
        """One line per encoder set: the goals with a right target that succeeded, the routes,
        the planner's time, the blocked reaches and the audit's verdict on them."""
        lines = []
        for r in self.runs:
            if not r.available:
                continue
            x = r.summary()["reach"]
            ro = x["routes"]
            plan = (
                f"planning {x['planning_ms_median']:.0f} / {x['planning_ms_p95']:.0f} ms "
                "(median / p95)"
                if x["planning_ms_median"] is not None
                else "no planning"
            )
            lines.append(
                f"- **{r.label}**: goals with the target within {SUCCESS_RADIUS_M * 100:.0f} cm "
                f"of the truth reached: {_pct(x['right_target_success_rate'])} "
                f"({x['right_target_successes']}/{x['right_target']}); routes: "
                f"{ro['local']} local, {ro['planned']} planned, {ro['none']} none (fallback "
                f"{_pct(x['fallback_share'])}); {plan}; blocked {x['blocked']}, of which the "
                f"audit found a collision-free configuration for {x['blocked_audit_feasible']}"
            )
        return "\n".join(lines)

    def in_a_row_markdown(self) -> str:
        rows = [(r, r.summary()["in_a_row"]) for r in self.runs if r.available]
        n = max((len(x) for _, x in rows), default=0)
        if not n:
            return ""
        head = "| encoders | " + " | ".join(f"{i} in a row %" for i in range(1, n + 1)) + " |"
        lines = [head, "|" + "---|" * (n + 1)]
        for r, x in rows:
            cells = [
                f"{_pct(x[str(i)]['success_rate'])} ({x[str(i)]['sequences']})"
                if str(i) in x
                else "–"
                for i in range(1, n + 1)
            ]
            lines.append(f"| {r.label} | " + " | ".join(cells) + " |")
        return "\n".join(lines)

    def to_markdown(self) -> str:
        """The whole report as Markdown (pictures by relative path)."""
        out = ["# Goal-reaching evaluation", ""]
        if self.reader:
            out += [f"Every goal's words were read by the `{self.reader}` reader.", ""]
        if self.mobile:
            out.append(
                f"A mobile base's goal succeeds when the base's centre ends within "
                f"{self.success_radius:g} m of the goal's ground truth on the floor (x, y: an "
                "object's box, where a sound was heard, a table's top, where an image was "
                "taken, the point a spatial relation names). Target error: the predicted "
                "target's distance to the truth on the floor. Collisions: contacts begun "
                "between the base and the room during its motions. The **oracle** encoders "
                "read the simulator's segmentation and the inserted clips' labels: a simulator "
                "upper bound, never the default."
            )
        else:
            out.append(
                "A goal succeeds when the robot's tool centre point ends within 10 cm of the "
                "goal's ground truth (an object's box, where a sound was heard, an area, the "
                "point a spatial relation names). R@k: the predicted target (where the robot "
                "was sent) lies within k of the truth. Contacts: robot-scene contact points "
                "during the motions. An **absent** goal asks for something the scene does not "
                "have: it succeeds when the map reports it not found (nothing moves), and "
                "recall and errors leave it out. The **oracle** encoders read the simulator's "
                "segmentation and the inserted clips' labels: a simulator upper bound, never "
                "the default."
            )
        out += ["", f"Task files: {', '.join(f'`{p}`' for p in self.task_files)}", ""]
        for r in self.runs:
            if r.available:
                names = ", ".join(f"{k}: {v}" for k, v in r.encoder_names.items() if k != "set")
                out.append(f"- **{r.label}**: {names}; {len(r.goals)} goals in {r.wall_s:.0f} s")
            else:
                out.append(f"- **{r.label}**: unavailable — {r.reason}")
        out += ["", "## Success by goal type", "", self.table_markdown(), ""]
        if not self.mobile:
            out += ["## The arm", "", self.reach_markdown(), ""]
        row = self.in_a_row_markdown()
        if row:
            out += [
                "## Goals in a row",
                "",
                "Share of sequences whose first n goals all succeeded (the arm goes on from "
                "where the previous goal left it; number of sequences in brackets).",
                "",
                row,
                "",
            ]
        for r in self.runs:
            for t in r.tasks:
                out += [f"## {t.task_name} — {r.label}", ""]
                f = t.figures
                if "scene" in f:
                    out += [
                        f"![{t.task_name}: scene from above]({f['scene']})",
                        "",
                        "Green: ground-truth boxes and (diamonds) truth points of spatial and "
                        "image goals; blue rings: where sounds were heard; red filled dots: "
                        "final TCP of a success, red rings with a cross: of a miss; yellow "
                        "crosses: predicted targets.",
                        "",
                    ]
                for key, path in f.items():
                    if key.startswith("heatmaps:"):
                        gid = key.split(":", 1)[1]
                        g = next(x for x in t.goals if x.goal_id == gid)
                        out += [f"**{g.type}: {g.text}** ({_outcome(g)})", "", f"![]({path})", ""]
                out += [
                    "<details><summary>every goal</summary>",
                    "",
                    _goal_table(t),
                    "",
                    "</details>",
                    "",
                ]
        return "\n".join(out)

    def write(self, out_dir: str | Path) -> Path:
        """Write ``report.md`` and ``results.json`` into ``out_dir``; return the report path."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        self.out_dir = out
        (out / "results.json").write_text(dumps(self.to_json()))
        path = out / "report.md"
        path.write_text(self.to_markdown())
        return path


def _outcome(g) -> str:
    if g.status == "unavailable":
        return f"unavailable: {g.reason}"
    if not g.has_place:  # an absent goal
        if g.success:
            return "success: not found"
        return f"miss: {g.reason}" if g.reason else "miss"
    if g.status == "not_found":
        return "not found"
    return f"{'success' if g.success else 'miss'}, TCP {_cm(g.error_m)} cm from the truth"


def _goal_table(t) -> str:
    lines = [
        "| goal | type | text | outcome | target error cm | reach | route | contacts |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for g in t.goals:
        text = g.text.replace("|", "/")
        lines.append(
            f"| {g.goal_id} | {g.type} | {text} | {_outcome(g)} | {_cm(g.target_error_m)} | "
            f"{g.reach or g.status}{f' (audit: {g.audit})' if g.audit else ''} | "
            f"{g.route or '–'} | {g.contacts} |"
        )
    return "\n".join(lines)


# ---------------------------------------------------------------------------- pictures
def _pixel(m, xy) -> tuple[int, int]:
    """(column, row) of a world point in the top view (x up the image, y to the left)."""
    g = m.grid
    nx, ny, _ = g.shape
    ix = (xy[0] - g.lower[0]) / g.voxel_size
    iy = (xy[1] - g.lower[1]) / g.voxel_size
    return round((ny - iy) * _SCALE), round((nx - ix) * _SCALE)


def scene_picture(m, ground_truth: GroundTruth, goals, regions) -> np.ndarray:
    """BGR top view of the map with ground truth, truths and final TCPs."""
    from tabletop.mapping.render import heatmap_views

    img = heatmap_views(m, np.zeros(m.grid.shape, np.float32), scale=_SCALE)["top"].copy()
    for o in ground_truth.objects:
        a = _pixel(m, o.aabb_max)
        b = _pixel(m, o.aabb_min)
        cv2.rectangle(img, a, b, _GREEN, 1)
        cv2.putText(img, o.label, (a[0], a[1] - 3), cv2.FONT_HERSHEY_SIMPLEX, 0.35, _WHITE, 1)
    for e in ground_truth.sound_events:
        c = _pixel(m, e.table_point)
        cv2.circle(img, c, 9, _BLUE, 2)
        cv2.putText(
            img, e.category, (c[0] + 10, c[1] + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35, _BLUE, 1
        )
    for g in goals:  # truths smaller than 2 cm across (spatial points, image cameras)
        b = regions[g.goal_id].boxes
        if len(b) == 1 and np.all(b[0, 1, :2] - b[0, 0, :2] < 0.02):
            cv2.drawMarker(img, _pixel(m, b[0, 0]), _GREEN, cv2.MARKER_DIAMOND, 9, 1)
    for g in goals:
        if g.target is not None:
            cv2.drawMarker(img, _pixel(m, g.target), _YELLOW, cv2.MARKER_CROSS, 8, 1)
        if g.tcp is None or g.status == "unavailable" or (g.success and not g.has_place):
            continue  # an absent goal's success: nothing moved
        c = _pixel(m, g.tcp)
        if g.success:
            cv2.circle(img, c, 4, _RED, -1)
        else:
            cv2.circle(img, c, 5, _RED, 1)
            cv2.drawMarker(img, c, _RED, cv2.MARKER_TILTED_CROSS, 8, 1)
    return _crop(m, img, _SCALE)


#: Pictures show the table from this x [m] on (the robot's base and the floor behind it left out).
_CROP_X_M = 0.15


def _crop(m, img: np.ndarray, scale: int) -> np.ndarray:
    """Rows of a top view (x up the image) from the far edge of the grid down to _CROP_X_M."""
    rows = round((m.grid.upper[0] - _CROP_X_M) / m.grid.voxel_size * scale)
    return img[: max(rows, 1)]


def _labelled(img: np.ndarray, text: str) -> np.ndarray:
    bar = np.full((22, img.shape[1], 3), 30, np.uint8)
    cv2.putText(bar, text, (4, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.45, _WHITE, 1)
    return np.vstack([bar, img])


def write_task_figures(
    out_dir, tf, encoders, m, ground_truth: GroundTruth, goals, regions, ctx
) -> dict:
    """Write the scene picture, heatmaps and query images of one task file; return
    {name: path relative to the report directory (two levels up)}."""
    from tabletop.mapping.render import heatmap_views

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rel = Path("figures") / out.parent.name / out.name
    figures = {}
    p = out / "scene.png"
    cv2.imwrite(str(p), scene_picture(m, ground_truth, goals, regions))
    figures["scene"] = str(rel / p.name)
    by_id = {g.goal_id: g for g in goals}
    for gid, maps in ctx.heatmaps.items():
        g = by_id.get(gid)
        if g is None:
            continue
        panels = []
        if gid in ctx.images:
            q = cv2.cvtColor(ctx.images[gid], cv2.COLOR_RGB2BGR)
            panels.append(_labelled(q, "query image"))
        for label, values in maps:
            v = _crop(m, heatmap_views(m, np.asarray(values), g.target, scale=4)["top"], 4)
            panels.append(_labelled(v, label))
        h = max(x.shape[0] for x in panels)
        panels = [
            np.vstack([x, np.zeros((h - x.shape[0], x.shape[1], 3), np.uint8)]) for x in panels
        ]
        p = out / f"heatmaps-{gid}.png"
        cv2.imwrite(str(p), np.hstack(panels))
        figures[f"heatmaps:{gid}"] = str(rel / p.name)
    return figures
