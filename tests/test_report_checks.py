"""The reports' checks: each row with a threshold passes for a good model and fails for a bad one."""

import pytest

from emogesture.eval.gesture_models import gesture_checks
from emogesture.eval.speech import speech_checks

ROW = dict(SRGR=1.0, BA=0.9, FGD=5.0, Div=10.0, GA=0.8, Jerk=1.0, Speed=0.3)


def _seams(ratio: float, share: float = 0.01, tail: float = 0.9, largest: float | None = None) -> dict:
    return {"max_jump_m": 0.02 * (ratio if largest is None else largest), "max_seam_jump_m": 0.02 * ratio, "p99_seam_jump_m": 0.02 * tail, "p99_inside_jump_m": 0.02,
            "seam_share_above_p99": share}


def _gesture(good: bool) -> dict:
    ours = ROW if good else dict(ROW, GA=0.2, FGD=9.0)  # a model that misses the emotion and the motion
    rows = {"GT": dict(ROW, FGD=0.0, GA=1.0, BA=1.0), "ours": ours,
            "ours, emotion auto": dict(ours, GA=ours["GA"] - (0.01 if good else 0.2)),
            "ours, emotion edit": dict(ROW, GA=0.8 if good else 0.1),
            "no prior": dict(ROW, FGD=6.0), "disjoint": dict(ROW, FGD=7.0),
            "GT, mismatched audio": dict(ROW, FGD=2.0, BA=0.99)}
    recon = {"mean pose": {"joint_error_m": 0.1}, "ours": {"joint_error_m": 0.02 if good else 0.05}}
    long = {"candidates_1": {**_seams(1.1 if good else 3.0, tail=0.9 if good else 1.6), "seeds": 4,
                             "p99_windows_own_seam_jump_m": 0.02},
            "candidates_4": _seams(0.8), "ground_truth": _seams(0.9, tail=0.8),
            "every_take": {**_seams(1.5 if good else 4.0, tail=0.85 if good else 1.3, largest=2.0 if good else 9.7),
                           "seam_candidates": 1,
                           "ground_truth": _seams(2.4, tail=1.0)}}
    return gesture_checks(rows, "ours", ["no prior", "disjoint"], "ours, emotion edit", recon, long, 0.02)


def test_every_gesture_check_passes_a_good_model_and_fails_a_bad_one():
    good, bad = _gesture(True), _gesture(False)
    thresholded = {name for name, c in good.items() if c["threshold"] is not None}
    assert len(thresholded) >= 8
    assert all(good[name]["pass"] for name in thresholded), {n: good[n] for n in thresholded if not good[n]["pass"]}
    assert not any(bad[name]["pass"] for name in thresholded), {n: bad[n] for n in thresholded if bad[n]["pass"]}
    # rows that cannot tell a good model from a bad one carry no threshold
    for name in good:
        if name.startswith(("BA", "Div", "long audio, 4 candidates")):
            assert good[name]["threshold"] is None and good[name]["pass"] is None, name
    assert not any("frames" in name for name in good)  # a frame count against its own formula is no check
    assert good["FGD / FGD(GT, mismatched audio) (reported)"]["value"] == pytest.approx(2.5)


def _speech(good: bool) -> dict:
    return {"EA": 0.93 if good else 0.3, "SA": 0.99 if good else 0.4,
            "chance": {"emotion": 0.125, "speaker": 0.125},
            "linear_probes": {"emotion_from_style": 0.2 if good else 0.86, "speaker_from_emotion": 0.25 if good else 0.89},
            "content_use": {"self": 0.30, "content_shuffled": 0.36 if good else 0.30, "time_mean": 0.33},
            "reconstruction_relative_to_self": {"Self": 1.0, "XCon": 1.0, "XEmo": 1.01, "XSty": 1.0}}


def test_every_speech_check_passes_a_good_model_and_fails_a_bad_one():
    good, bad = speech_checks(_speech(True)), speech_checks(_speech(False))
    thresholded = {name for name, c in good.items() if c["threshold"] is not None}
    assert len(thresholded) == 5
    assert all(good[n]["pass"] for n in thresholded) and not any(bad[n]["pass"] for n in thresholded)
    near = good["emotion read from the style latent: near chance (0.125)"]["threshold"]
    assert near == pytest.approx(0.125 + 0.25 * 0.875)
    assert good["XCon / Self (reported)"]["pass"] is None  # equal to Self for any decoder that ignores content
