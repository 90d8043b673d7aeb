"""Whether two evaluations' results are the same goal for goal: their JSON (``results.json``,
or ``tabletop eval --json --goals``) compared field by field, timings and run facts aside.

```python
from tabletop.eval.compare import compare_results

diffs = compare_results(serial.to_json(), parallel.to_json())
assert not diffs, diffs  # ["rows[0].tasks[1].goals[3].tcp: [...] != [...]", ...]
```

Left out (:data:`IGNORED`): wall times (``time_s``, ``planning_s``, ``scan_s``, ``map_s``,
``wall_s``, ``time_per_goal_s``, ``planning_ms_median``, ``planning_ms_p95``), whether a
task's scan and map came from the cache (``cached``: which of two units that share a map
builds it depends on which starts first), where the report was written (``report``) and
where a task's map and recording are cached (``map_file``, ``recording_dir``).
Everything else must be equal: statuses, reasons, targets, final TCPs, errors, successes,
contacts, routes, code, the summaries.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

__all__ = ["IGNORED", "TIMING_FIELDS", "compare_results", "goal_count", "load_results"]

#: Wall-time fields: they differ between any two runs.
TIMING_FIELDS = frozenset(
    {
        "time_s",
        "planning_s",
        "scan_s",
        "map_s",
        "wall_s",
        "time_per_goal_s",
        "planning_ms_median",
        "planning_ms_p95",
    }
)
#: Every field :func:`compare_results` leaves out: the timings, the cache's state, the report's
#: place, and where a task's map and recording are cached (``map_file``, ``recording_dir``).
IGNORED = TIMING_FIELDS | {"cached", "report", "map_file", "recording_dir"}


def load_results(path: str | Path) -> dict:
    """An evaluation's JSON: a ``results.json``, a directory holding one (a report directory),
    or the output of ``tabletop eval --json --goals``."""
    from tabletop.paths import input_file_problem

    expected = (
        "give an evaluation output directory holding results.json, or the results.json file "
        "(or `tabletop eval --json` output)"
    )
    p = Path(path)
    if str(path) != "" and p.is_dir():
        p = p / "results.json"
        if not p.exists():
            raise ValueError(
                f"{path} is a directory without results.json, not an evaluation output: {expected}"
            )
    problem = input_file_problem(p)
    if problem is not None:
        raise ValueError(f"{str(p) if str(path) else ''!r} {problem}: {expected}")
    what = "is not an evaluation results file (a results.json, a report directory holding one, "
    what += "or `tabletop eval --json` output)"
    try:
        raw = p.read_bytes()
    except IsADirectoryError:
        raise ValueError(f"{p} {what}: it is a directory") from None
    if not raw.strip():
        raise ValueError(f"{p} {what}: the file is empty")
    try:
        d = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise ValueError(f"{p} {what}: not UTF-8 text (a binary file?)") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"{p} {what}: not valid JSON ({e}; truncated?)") from None
    _check_results(d, p, what)
    return d


def _check_results(d, p: Path, what: str) -> None:
    """An evaluation's JSON is an object with a ``rows`` list of objects (each with a
    ``tasks`` list), or a robustness run's ``results`` object of such evaluations."""
    if not isinstance(d, dict):
        raise ValueError(f"{p} {what}: it holds a JSON {type(d).__name__}, not an object")
    if "rows" not in d and isinstance(d.get("results"), dict) and d["results"]:
        for name, sub in d["results"].items():
            _check_results(sub, p, f"{what}, its results[{name!r}]")
        return
    rows = d.get("rows")
    if not isinstance(rows, list):
        keys = ", ".join(sorted(map(str, d))) or "none"
        raise ValueError(f"{p} {what}: it has no 'rows' list (its keys: {keys})")
    for i, r in enumerate(rows):
        if not isinstance(r, dict) or not isinstance(r.get("tasks"), list):
            raise ValueError(f"{p} {what}: rows[{i}] is not an object with a 'tasks' list")


def compare_results(a: dict, b: dict, ignored: frozenset[str] = IGNORED) -> list[str]:
    """The differences between two evaluations' JSON, one line each (empty: the same), fields
    named in ``ignored`` left out at every depth."""
    out: list[str] = []
    _diff(a, b, "", ignored, out)
    return out


def goal_count(d: dict) -> int:
    """How many goal outcomes an evaluation's JSON holds (every row's, every task's)."""
    return sum(len(t.get("goals", ())) for r in d.get("rows", ()) for t in r.get("tasks", ()))


def _diff(a, b, where: str, ignored, out: list[str]) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=str):
            if k in ignored:
                continue
            at = f"{where}.{k}" if where else str(k)
            if k not in a or k not in b:
                out.append(f"{at}: only in the {'second' if k not in a else 'first'}")
            else:
                _diff(a[k], b[k], at, ignored, out)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{where}: {len(a)} items != {len(b)} items")
        for i, (x, y) in enumerate(zip(a, b, strict=False)):
            _diff(x, y, f"{where}[{i}]", ignored, out)
    elif type(a) is not type(b) or a != b:
        if not (_number(a) and _number(b) and (a == b or (math.isnan(a) and math.isnan(b)))):
            out.append(f"{where}: {_short(a)} != {_short(b)}")  # (1 == 1.0; NaN == NaN)


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _short(x) -> str:
    s = json.dumps(x)
    return s if len(s) <= 120 else s[:117] + "..."
