"""Units for tests/test_eval_parallel.py's worker processes: a light module (a spawned worker
imports it to find the function), so that starting a pool stays cheap."""

import os

from tabletop.errors import ConfigError, GoalNotFound


def boom(x):
    """x * 10; 2 raises an error that does not survive pickling as it is, 3 one that does."""
    if x == 2:
        raise GoalNotFound("obj='x'", "nothing there")
    if x == 3:
        raise ConfigError("bad value 3")
    return x * 10


def threads():
    """(OMP_NUM_THREADS, torch's intra-op threads) in the worker."""
    import torch

    return os.environ["OMP_NUM_THREADS"], torch.get_num_threads()
