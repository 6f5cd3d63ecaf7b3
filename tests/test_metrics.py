"""Evaluation metrics (docs/design.md, 'Metrics'): each test checks a value that a wrong implementation would miss."""

from __future__ import annotations

import inspect
import math

import numpy as np
import pytest
from scipy import linalg

from emogesture.motion.skeleton import LOWER_BODY_JOINTS
from emogesture.eval import classification as cls
from emogesture.eval import metrics as M
from emogesture.eval.plots import save_confusion_matrix

FPS = 30


# ------------------------------------------------------------------ constants
def test_defaults_match_metric_constants():
    c = M.METRIC_CONSTANTS
    expect = {
        M.frechet_distance: {"eps": c["fgd_eps"]},
        M.diversity: {"num_pairs": c["div_num_pairs"], "seed": c["div_seed"]},
        M.motion_beats: {"fps": c["fps"], "order": c["beat_order"], "threshold": c["beat_threshold"],
                         "rule": c["beat_rule"]},
        M.beat_align: {"sigma": c["beat_sigma_s"], "direction": c["beat_direction"]},
        M.srgr: {"delta": c["srgr_delta_m"], "sem_scale": c["srgr_sem_scale"]},
        M.jerk: {"fps": c["fps"]},
        M.wrist_jerk: {"fps": c["fps"], "wrist_joints": c["wrist_joints"]},
        M.speed: {"fps": c["fps"]},
        M.wrist_speed: {"fps": c["fps"], "wrist_joints": c["wrist_joints"]},
    }
    for fn, params in expect.items():
        sig = inspect.signature(fn)
        for name, value in params.items():
            assert sig.parameters[name].default == value, (fn.__name__, name)
    assert (c["fgd_eps"], c["div_num_pairs"], c["beat_order"], c["beat_threshold"]) == (1e-6, 300, 7, 0.1)
    assert (c["beat_sigma_s"], c["srgr_delta_m"], c["srgr_sem_scale"], c["fps"]) == (0.3, 0.1, 0.165, 30)
    assert c["arm_joints"] == (16, 17, 18, 19, 20, 21) and c["wrist_joints"] == (20, 21)
    assert len(M.UPPER_BODY_JOINTS) == 47 and not {1, 2, 4, 5, 7, 8, 10, 11} & set(M.UPPER_BODY_JOINTS)


# ------------------------------------------------------------------ FGD
def test_frechet_of_a_set_with_itself_is_zero():
    rng = np.random.default_rng(0)
    f = rng.normal(size=(400, 16)) @ rng.normal(size=(16, 16)) + 3.0
    scale = np.trace(np.cov(f, rowvar=False))
    assert M.frechet_distance(f, f) < 1e-6 * scale
    g = rng.normal(size=(10, 32))  # rank-deficient covariance: eps keeps it defined
    assert abs(M.frechet_distance(g, g)) < 1e-4 and np.isfinite(M.frechet_distance(g, g[::-1] + 1.0))


def _closed_form(mu1, s1, mu2, s2):
    r1 = linalg.sqrtm(s1).real
    return float(np.sum((mu1 - mu2) ** 2) + np.trace(s1 + s2 - 2 * linalg.sqrtm(r1 @ s2 @ r1).real))


def test_frechet_of_gaussian_samples_matches_true_parameters():
    rng = np.random.default_rng(1)
    d, n = 4, 40_000
    a, b = rng.normal(size=(d, d)), rng.normal(size=(d, d))
    s1, s2 = a @ a.T / d + np.eye(d), b @ b.T / d + 0.5 * np.eye(d)
    mu1, mu2 = np.zeros(d), np.array([1.0, -0.5, 0.25, 2.0])
    x = rng.multivariate_normal(mu1, s1, size=n)
    y = rng.multivariate_normal(mu2, s2, size=n)
    truth = _closed_form(mu1, s1, mu2, s2)
    assert truth > 5.0
    assert M.frechet_distance(x, y) == pytest.approx(truth, rel=0.03)
    assert M.frechet_distance(x, y + 1.0) > truth + 3.0  # a further shift of the mean is seen


def test_frechet_from_stats_with_diagonal_covariances_is_analytic():
    a, b = np.array([0.5, 2.0, 9.0]), np.array([4.0, 1.0, 0.25])
    mu1, mu2 = np.array([1.0, 2.0, 3.0]), np.array([0.0, 2.5, 1.0])
    expected = np.sum((mu1 - mu2) ** 2) + np.sum((np.sqrt(a) - np.sqrt(b)) ** 2)
    got = M.frechet_from_stats(mu1, np.diag(a), mu2, np.diag(b), eps=0.0)
    assert got == pytest.approx(expected, rel=1e-10)
    mu, sig = M.gaussian_stats(np.array([[0.0, 1.0], [2.0, 3.0], [4.0, 2.0]]))
    np.testing.assert_allclose(mu, [2.0, 2.0])
    np.testing.assert_allclose(sig, [[4.0, 1.0], [1.0, 1.0]])  # unbiased (N-1) covariance
    with pytest.raises(ValueError):
        M.frechet_distance(np.zeros((1, 3)), np.zeros((5, 3)))


# ------------------------------------------------------------------ Div
def test_diversity_all_pairs_and_seeding():
    pts = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0]])  # pair distances 3, 4, 5
    assert M.diversity(pts, num_pairs=None) == pytest.approx(4.0)
    assert M.diversity(np.array([[0.0, 0.0], [6.0, 8.0]]), num_pairs=50) == pytest.approx(10.0)  # i != j
    f = np.random.default_rng(3).normal(size=(50, 8))
    assert M.diversity(f, seed=5) == M.diversity(f, seed=5)
    assert M.diversity(f, seed=5) != M.diversity(f, seed=6)
    assert M.diversity(f, rng=np.random.default_rng(5)) == M.diversity(f, seed=5)
    big = M.diversity(f, num_pairs=200_000, seed=0)
    assert big == pytest.approx(M.diversity(f, num_pairs=None), rel=0.01)


# ------------------------------------------------------------------ classification
def test_classification_report_hand_example():
    y_true = [0, 0, 0, 1, 1, 2, 2, 2]
    y_pred = [0, 0, 1, 1, 2, 2, 2, 0]
    rep = cls.classification_report(y_true, y_pred, num_classes=4)
    assert rep["accuracy"] == pytest.approx(5 / 8)
    np.testing.assert_array_equal(rep["confusion"], [[2, 1, 0, 0], [0, 1, 1, 0], [1, 0, 2, 0], [0, 0, 0, 0]])
    np.testing.assert_allclose(rep["f1"][:3], [2 / 3, 1 / 2, 2 / 3])
    assert np.isnan(rep["f1"][3]) and not rep["present"][3]
    assert rep["macro_f1"] == pytest.approx(11 / 18)  # absent class 3 excluded
    np.testing.assert_array_equal(rep["support"], [3, 2, 3, 0])
    # a class predicted but never true counts with F1 = 0
    rep2 = cls.classification_report([0, 0], [0, 1], num_classes=3)
    assert rep2["macro_f1"] == pytest.approx((2 / 3 + 0.0) / 2)
    from sklearn.metrics import f1_score

    rng = np.random.default_rng(0)
    t, p = rng.integers(0, 5, 200), rng.integers(0, 6, 200)
    present = sorted(set(t) | set(p))
    ours = cls.classification_report(t, p, num_classes=8)["macro_f1"]
    assert ours == pytest.approx(f1_score(t, p, average="macro", labels=present))
    with pytest.raises(ValueError):
        cls.classification_report([0, 9], [0, 1], num_classes=4)


def test_gesture_accuracy_from_logits_and_labels():
    logits = np.array([[2.0, 1.0, 0.0], [0.0, 0.1, 3.0], [0.5, 0.4, 0.0], [0.0, 5.0, 1.0]])
    labels = np.array([0, 2, 1, 1])
    assert cls.gesture_accuracy(logits, labels) == pytest.approx(0.75)
    assert cls.gesture_accuracy(np.array([0, 2, 0, 1]), labels) == pytest.approx(0.75)
    with pytest.raises(ValueError):
        cls.gesture_accuracy(logits, labels[:3])


# ------------------------------------------------------------------ beat align
def test_beat_align_values_and_directions():
    onsets = np.array([0.5, 1.5, 2.5, 3.5])
    assert M.beat_align(onsets, onsets) == pytest.approx(1.0)
    for delta in (0.05, 0.1, 0.2, 0.3, 0.45):
        got = M.beat_align(onsets + delta, onsets[::-1])
        assert got == pytest.approx(math.exp(-delta**2 / (2 * 0.3**2)), rel=1e-12)
        assert M.beat_align(onsets - delta, onsets, sigma=0.1) == pytest.approx(math.exp(-delta**2 / 0.02))
    sparse = np.array([0.5, 2.5])  # every motion beat is on an onset, half the onsets have no beat
    assert M.beat_align(sparse, onsets) == pytest.approx(1.0)
    e = math.exp(-1.0 / (2 * 0.3**2))
    assert M.beat_align(sparse, onsets, direction="audio_to_motion") == pytest.approx((2 + 2 * e) / 4)
    assert math.isnan(M.beat_align([], onsets)) and M.beat_align(onsets, []) == 0.0
    assert math.isnan(M.beat_align(onsets, [], direction="audio_to_motion"))
    with pytest.raises(ValueError):
        M.beat_align(onsets, onsets, direction="both")


def _strokes(stops, num_frames, rng):
    """[T, 3] path through random points, eased (1-cos) so the speed is 0 exactly at every stop frame."""
    knots = [0, *stops, num_frames - 1]
    pts = rng.normal(scale=0.3, size=(len(knots), 3))
    pts[2] = pts[1] + 0.5 * (pts[1] - pts[0])  # one stop continues in the same direction
    x = np.zeros((num_frames, 3))
    for k in range(len(knots) - 1):
        t0, t1 = knots[k], knots[k + 1]
        u = (np.arange(t0, t1 + 1) - t0) / (t1 - t0)
        x[t0:t1 + 1] = pts[k] + (pts[k + 1] - pts[k]) * ((1 - np.cos(np.pi * u)) / 2)[:, None]
    return x


def test_motion_beats_finds_known_stops():
    rng = np.random.default_rng(0)
    stops = [[20, 38, 55, 75, 92, 110], [15, 30, 50, 66, 85, 105]]
    traj = np.stack([_strokes(s, 130, rng) for s in stops], axis=1)  # [T, 2, 3]
    per_joint = M.motion_beats(traj, per_joint=True)
    for found, want in zip(per_joint, stops):
        frames = np.round(found * FPS).astype(int)
        assert len(frames) == len(want) and np.all(np.abs(frames - np.array(want)) <= 1), (frames, want)
    merged = M.motion_beats(traj)
    np.testing.assert_allclose(merged, np.sort(np.concatenate(per_joint)))
    np.testing.assert_allclose(M.motion_beats(traj * 7.0), merged)  # speed is normalised per joint
    # "value" rule (public BEAT/EMAGE code) keeps only minima whose own speed > 0.1: a strict subset here
    by_value = M.motion_beats(traj, rule="value")
    assert 0 < by_value.size < merged.size and set(by_value.tolist()) <= set(merged.tolist())
    # inside a 55-joint skeleton only the arm joints 16..21 count
    body = np.cumsum(rng.normal(size=(130, 55, 3)), axis=0)
    body[:, list(M.ARM_JOINTS)] = np.concatenate([traj] * 3, axis=1)
    np.testing.assert_allclose(M.motion_beats(body), np.sort(np.concatenate([merged] * 3)))


def test_motion_beats_slowdowns_and_holds():
    t = np.arange(200)
    x = np.zeros((200, 1, 3))
    x[:, 0, 0] = 0.02 * t + (0.01 / (2 * np.pi / 20)) * np.sin(2 * np.pi * t / 20)  # speed dips to 1/2, never 0
    for rule in ("moving_before", "value"):
        frames = np.round(M.motion_beats(x, rule=rule) * FPS).astype(int)
        np.testing.assert_array_equal(frames, np.arange(10, 191, 20))
    rng = np.random.default_rng(2)
    hold = _strokes([20, 40], 60, rng)
    tail = hold[-1] + rng.normal(scale=1e-4, size=(90, 3))  # a hold with tiny jitter
    traj = np.concatenate([hold, tail])[:, None]
    frames = np.round(M.motion_beats(traj) * FPS).astype(int)
    assert {20, 40} <= set(frames.tolist()) and np.all(frames < 60 + 7 + 2)
    assert M.motion_beats(np.zeros((2, 6, 3))).size == 0


# ------------------------------------------------------------------ SRGR
def test_srgr_weighted_recall():
    rng = np.random.default_rng(0)
    t, upper = 4, np.array(M.UPPER_BODY_JOINTS)
    gt = rng.normal(size=(t, 55, 3))
    sem = np.array([0.0, 0.5, 1.0, 0.165])
    hits = np.array([10, 47, 24, 0])
    err = np.full((t, 55), 0.2)
    err[:, list(LOWER_BODY_JOINTS)] = 0.0  # lower body is perfect but must not count
    for f in range(t):
        err[f, upper[rng.permutation(47)[: hits[f]]]] = 0.05
    direction = rng.normal(size=(t, 55, 3))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    pred = gt + err[..., None] * direction
    expected = np.sum(sem / 0.165 * hits) / (t * 47)
    assert M.srgr(pred, gt, sem) == pytest.approx(expected)
    # explicit 6 joints, half within delta; delta is strict (error == delta is a miss)
    g6, p6 = np.zeros((2, 6, 3)), np.zeros((2, 6, 3))
    p6[:, 3:, 0] = 0.1
    assert M.srgr(p6, g6, [0.33, 0.33]) == pytest.approx(0.5 * 0.33 / 0.165)
    assert M.srgr(p6, g6, [0.33, 0.33], delta=0.11) == pytest.approx(0.33 / 0.165)
    with pytest.raises(ValueError):
        M.srgr(p6, g6, [0.3])


# ------------------------------------------------------------------ jerk
def test_jerk_of_cubic_and_linear_trajectories():
    tt = np.arange(40) / FPS
    a = np.array([0.5, -2.0])
    x = np.zeros((40, 2, 3))
    x[:, :, 1] = a[None] * tt[:, None] ** 3
    assert M.jerk(x) == pytest.approx(6 * np.mean(np.abs(a)), rel=1e-6)
    assert M.jerk(x[:, 0], fps=FPS) == pytest.approx(3.0, rel=1e-6)
    lin = np.zeros((40, 2, 3)) + tt[:, None, None] * np.array([0.3, -1.0, 2.0])
    assert M.jerk(lin) < 1e-6
    body = np.random.default_rng(0).normal(size=(40, 55, 3))
    body[:, 20:22] = x
    assert M.wrist_jerk(body) == pytest.approx(6 * np.mean(np.abs(a)), rel=1e-6)
    with pytest.raises(ValueError):
        M.jerk(np.zeros((3, 2, 3)))


def test_speed_of_linear_trajectories():
    tt = np.arange(40) / FPS
    v = np.array([[0.3, -1.0, 2.0], [0.0, 0.0, 0.5]])  # m/s, one velocity per joint
    x = tt[:, None, None] * v[None]
    assert M.speed(x) == pytest.approx(np.linalg.norm(v, axis=1).mean(), rel=1e-9)
    assert M.speed(np.zeros((5, 2, 3))) == 0.0
    body = np.random.default_rng(1).normal(size=(40, 55, 3))
    body[:, 20:22] = x
    assert M.wrist_speed(body) == pytest.approx(np.linalg.norm(v, axis=1).mean(), rel=1e-9)
    assert M.wrist_speed(body * 2) > M.wrist_speed(body)  # faster hands, higher speed
    with pytest.raises(ValueError):
        M.speed(np.zeros((1, 2, 3)))


# ------------------------------------------------------------------ plots
def test_confusion_matrix_png_and_overwrite_protection(tmp_path):
    cm = np.array([[5, 1, 0], [2, 3, 0], [0, 0, 0]])
    path = tmp_path / "figs" / "cm.png"
    out = save_confusion_matrix(cm, ["neutral", "happy", "angry"], path, title="GA")
    assert out == path and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    before = path.read_bytes()
    with pytest.raises(FileExistsError):
        save_confusion_matrix(cm, ["a", "b", "c"], path)
    assert path.read_bytes() == before
    save_confusion_matrix(cm * 2, ["a", "b", "c"], path, title="other", overwrite=True)
    assert path.read_bytes() != before and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in path.parent.iterdir()) == ["cm.png"]  # no temp files left
    with pytest.raises(ValueError):
        save_confusion_matrix(cm, ["a", "b"], tmp_path / "bad.png")
