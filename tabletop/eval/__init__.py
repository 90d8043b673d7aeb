"""Evaluation: goals generated from a recording's ground truth, scored against it."""

from tabletop.eval.map_goals import MapGoal, evaluate_map_goals, map_goals

__all__ = ["MapGoal", "evaluate_map_goals", "map_goals"]
