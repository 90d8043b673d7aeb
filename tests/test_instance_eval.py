"""The per-instance measure of an image encoder, on the simulator oracle (whose fused
embeddings are its labels' text embeddings: every instance must be named right)."""

import pytest

from tabletop.eval.instance_eval import INSTANCE_EVAL_SEEDS, evaluate_instances


@pytest.mark.slow  # a held-out scene scanned and mapped: about a minute of CPU
def test_the_oracle_names_every_instance_of_a_held_out_scene():
    short = {"episodes": 3, "episode_s": 2.5, "speed": 0.45, "repeat_sounds": 1}
    r = evaluate_instances("oracle", seeds=INSTANCE_EVAL_SEEDS[:1], cache_dir=None, scan=short)
    assert r["instance_eval_objects"] >= 6 and r["instance_eval_instances"] >= 6
    assert r["vision_instance_top1_heldout"] == 1.0
    assert r["vision_instance_label_top1_heldout"] >= 0.8  # colour: measured, shaded
    assert r["instance_segmentation_single"] >= 0.8
