"""Confidence calibration: Platt fits, reliability, and the calibration file format."""

import json

import numpy as np
import pytest

from tabletop.errors import AssetError, ConfigError
from tabletop.eval.calibration import fit_calibration
from tabletop.mapping.calibration import (
    UNCALIBRATED,
    Calibration,
    Platt,
    expected_calibration_error,
    fit_platt,
    load_calibration,
)


def _samples(a, b, n, seed=0):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-0.2, 0.6, n)
    y = rng.random(n) < Platt(a, b)(x)
    return x, y


def test_fit_recovers_a_known_logistic():
    x, y = _samples(12.0, -2.0, 4000)
    f = fit_platt(x, y)
    assert f.a == pytest.approx(12.0, rel=0.15)
    assert f.b == pytest.approx(-2.0, abs=0.3)


def test_fitted_confidences_are_calibrated_and_the_prior_is_not():
    x, y = _samples(6.0, -1.0, 3000, seed=1)
    f = fit_platt(x[:1500], y[:1500])
    assert expected_calibration_error(f(x[1500:]), y[1500:]) < 0.05
    # a much steeper prior is overconfident on the same data
    assert expected_calibration_error(UNCALIBRATED(x[1500:]), y[1500:]) > 0.1


def test_separable_data_stays_finite():
    f = fit_platt([0.0, 0.1, 0.5, 0.6], [False, False, True, True])
    assert np.isfinite([f.a, f.b]).all() and f(0.55) > 0.5 > f(0.05)


def test_fit_needs_both_classes_and_pairs():
    with pytest.raises(ConfigError, match="one class"):
        fit_platt([0.1, 0.2, 0.3, 0.4], [True] * 4)
    with pytest.raises(ConfigError, match="paired"):
        fit_platt([0.1, 0.2], [True, False, True])


def test_fit_calibration_reports_held_out_figures():
    x, y = _samples(10.0, -2.0, 400, seed=2)
    s = [{"modality": "object", "margin": m, "correct": bool(c)} for m, c in zip(x, y, strict=True)]
    cal = fit_calibration("default", s[:200], s[200:])
    assert cal.calibrated == ("object",)
    r = cal.report["object"]
    assert r["test_samples"] == 200 and 0.5 < r["decision_accuracy_test"] <= 1.0
    assert r["ece_test"] < r["ece_test_uncalibrated"]
    # modalities without samples keep the prior
    assert cal.confidence("sound", 0.2) == pytest.approx(UNCALIBRATED(0.2))
    with pytest.raises(ConfigError, match="valid"):
        cal.confidence("smell", 0.2)


def test_file_round_trip_and_errors(tmp_path):
    cal = Calibration("default", {"object": Platt(8.0, -1.5)}, {"object": {"ece_test": 0.03}})
    p = cal.save(tmp_path / "default.json")
    back = load_calibration("default", p)
    assert back.models == cal.models and back.report == cal.report
    assert load_calibration("no-such-set").models == {}  # no file: the prior
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "tabletop-calibration", "version": 1, "models": {}}))
    with pytest.raises(AssetError, match="malformed"):
        load_calibration("x", bad)
    bad.write_text(
        json.dumps(
            {
                "format": "tabletop-calibration",
                "version": 1,
                "encoder_set": "x",
                "models": {"smell": {"a": 1, "b": 0}},
            }
        )
    )
    with pytest.raises(AssetError, match="unknown modality"):
        load_calibration("x", bad)
    with pytest.raises(AssetError, match="does not exist"):
        load_calibration("x", tmp_path / "missing.json")
    d = {"format": "tabletop-calibration", "version": 1, "encoder_set": "x"}
    for field, value, needle in (
        ("models", {"object": {"a": float("nan"), "b": 0}}, "models.object: a and b must be"),
        ("thresholds", {"object": float("inf")}, "thresholds.object must be a finite"),
    ):
        with pytest.raises(AssetError, match=needle):
            Calibration.from_json({**d, "models": {}, field: value}, "the map's calibration")


def test_operating_point_keeps_most_right_answers(tmp_path):
    rng = np.random.default_rng(3)
    right = rng.normal(0.35, 0.1, 200)
    wrong = rng.normal(0.15, 0.05, 600)
    s = [{"modality": "sound", "margin": m, "correct": True} for m in right]
    s += [{"modality": "sound", "margin": m, "correct": False} for m in wrong]
    rng.shuffle(s)
    cal = fit_calibration("default", s[:400], s[400:])
    t = cal.thresholds["sound"]
    r = cal.report["sound"]
    assert 0.9 <= r["right_kept_test"] <= 1.0 and r["wrong_refused_test"] > 0.3
    # the decision follows the threshold, not the (base-rate driven) confidence
    assert cal.found("sound", t + 0.01, confidence=0.1, min_confidence=0.5)
    assert not cal.found("sound", t - 0.01, confidence=0.9, min_confidence=0.5)
    # modalities without a threshold use the confidence
    assert cal.found("object", 0.0, confidence=0.6, min_confidence=0.5)
    back = load_calibration("default", cal.save(tmp_path / "c.json"))
    assert back.thresholds == cal.thresholds


def test_image_gets_a_confidence_but_its_module_decides_found():
    rng = np.random.default_rng(4)
    s = [
        {"modality": "image", "margin": m, "correct": bool(m > 0.3), "found": bool(m > 0.35)}
        for m in rng.uniform(-0.2, 0.9, 300)
    ]
    cal = fit_calibration("default", s[:150], s[150:])
    assert "image" in cal.models and "image" not in cal.thresholds
    assert cal.confidence("image", 0.8) > 0.9 > 0.1 > cal.confidence("image", 0.0)
    r = cal.report["image"]
    # kept / refused come from the module's own decision: found above 0.35, right above 0.3
    test = s[150:]
    right = [x for x in test if x["correct"]]
    assert r["threshold_margin"] is None
    assert r["right_kept_test"] == pytest.approx(np.mean([x["found"] for x in right]))
    assert r["right_kept_test"] < 1.0 and r["wrong_refused_test"] == 1.0


def test_keep_prior_sets_fits_aside(tmp_path, capsys):
    cal = Calibration(
        "oracle",
        {"object": Platt(8.0, -1.5), "image": Platt(9.0, -3.0)},
        {"object": {"ece_test": 0.03}},
        {"object": 0.4},
    )
    kept = cal.keep_prior(["object"])
    assert kept.calibrated == ("image",) and kept.thresholds == {}
    assert kept.confidence("object", 0.2) == pytest.approx(UNCALIBRATED(0.2))
    back = load_calibration("oracle", kept.save(tmp_path / "o.json"))
    assert back.report["prior_kept"]["object"] == {
        "model": {"a": 8.0, "b": -1.5},
        "threshold": 0.4,
        "report": {"ece_test": 0.03},
    }
    with pytest.raises(ConfigError, match="unknown modalities"):
        cal.keep_prior(["smell"])
    from tabletop.cli import main

    assert main(["calibrate", "--keep-prior", "object,smell", "--out", str(tmp_path / "x")]) == 2
    assert "valid" in capsys.readouterr().err and not (tmp_path / "x").exists()


def test_a_modality_with_too_few_queries_keeps_the_prior():
    few = [
        {"modality": "area", "query": f"q{i}", "margin": 0.1 * i, "correct": i % 2 == 0}
        for i in range(3)
    ]
    cal = fit_calibration("default", few, few)
    assert "area" not in cal.models and cal.confidence("area", 0.2) == UNCALIBRATED(0.2)


def test_the_operating_point_sits_in_the_gap_below_the_kept_right_answers():
    from tabletop.eval.calibration import operating_point

    right = np.linspace(0.9, 1.0, 100)
    # separable: halfway between the 5 % quantile of the right margins and the highest wrong one
    t = operating_point(right, np.array([0.0, 0.1, 0.3]))
    assert t == pytest.approx((np.quantile(right, 0.05, method="lower") + 0.3) / 2)
    # a wrong margin above the quantile does not move it up; none below: the quantile itself
    assert operating_point(right, np.array([0.95])) == np.quantile(right, 0.05, method="lower")
    assert operating_point(right, np.array([])) == np.quantile(right, 0.05, method="lower")


def test_the_balanced_operating_point_refuses_wrong_answers_among_weak_right_ones():
    from tabletop.eval.calibration import operating_point

    # weak right answers scattered among the wrong ones, the rest well clear of them
    right = np.concatenate([np.linspace(0.05, 0.4, 6), np.linspace(0.8, 1.0, 30)])
    wrong = np.concatenate([np.linspace(0.0, 0.3, 30), [0.9]])
    keep = operating_point(right, wrong)
    t = operating_point(right, wrong, rule="balanced")
    # keeping 95 % of the right answers accepts most wrong ones; balanced refuses all but one
    assert np.mean(wrong < keep) < 0.5 and np.mean(wrong < t) == 30 / 31
    assert np.mean(right >= t) == 32 / 36
    # the best share kept + share refused is at the right answer 0.33 (of 0.05 ... 0.40, by
    # 0.07), moved to the middle of the gap to the highest wrong answer under it (0.30)
    assert t == pytest.approx((0.33 + 0.30) / 2)
    with pytest.raises(ConfigError, match="valid"):
        operating_point(right, wrong, rule="median")


def test_room_maps_read_their_own_calibration_where_one_was_fitted(tmp_path, capsys):
    from tabletop.eval.harness import committed_calibration, map_config
    from tabletop.mapping.calibration import CALIBRATION_DIR

    table = committed_calibration("default", map_config())
    assert table.thresholds == load_calibration("default").thresholds
    room = committed_calibration("default", map_config(image_network="room", image_scale=2))
    if (CALIBRATION_DIR / "default-room.json").is_file():
        assert room.report.get("rooms") is True
        assert room.thresholds["object"] != table.thresholds["object"]
    else:
        assert room.thresholds == table.thresholds
    # the oracle is one encoder whatever the network: the set's own file
    assert committed_calibration("oracle", map_config(image_network="room")).encoder_set == "oracle"
    from tabletop.cli import main

    out = tmp_path / "r.json"
    assert main(["calibrate", "--rooms", "--scenes", "2", "--out", str(out)]) == 2
    assert "--rooms" in capsys.readouterr().err and not out.exists()
    assert main(["calibrate", "--rooms", "--encoders", "oracle", "--out", str(out)]) == 2
