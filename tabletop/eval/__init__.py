"""Evaluation: goal-reaching task files (scene, scan, goals with ground truth) run through the
robot API in simulation, scored and reported per goal type; map-level goals from a recording.

Typical use::

    from tabletop.eval import run_eval

    result = run_eval("demo", encoders="oracle", out_dir="out/eval")
    print(result.to_markdown())
"""

from tabletop.eval.map_goals import MapGoal, evaluate_map_goals, map_goals
from tabletop.eval.report import EvalResult
from tabletop.eval.results import EncoderRun, GoalResult, TaskRun
from tabletop.eval.runner import collect_task_files, evaluate_task_file, run_eval
from tabletop.eval.tasks import (
    GOAL_TYPES,
    Goal,
    TaskFile,
    TaskFileError,
    Truth,
    load_tasks,
    parse_tasks,
)
from tabletop.eval.truth import Region, resolve_truth

__all__ = [
    "GOAL_TYPES",
    "EncoderRun",
    "EvalResult",
    "Goal",
    "GoalResult",
    "MapGoal",
    "Region",
    "TaskFile",
    "TaskFileError",
    "TaskRun",
    "Truth",
    "collect_task_files",
    "evaluate_map_goals",
    "evaluate_task_file",
    "load_tasks",
    "map_goals",
    "parse_tasks",
    "resolve_truth",
    "run_eval",
]
