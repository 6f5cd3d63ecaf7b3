"""The corpus generator's hands and body turn, on their own (the corpus tests check whole takes)."""

import numpy as np
import pytest

from emogesture.data.synthetic import hands
from emogesture.data.synthetic.gestures import LISTENER_YAW, listener_yaw


def _mean_angle_deg(poses: np.ndarray) -> float:
    return float(np.degrees(np.linalg.norm(poses, axis=-1)).mean())


def test_a_hand_at_rest_is_loosely_curled_and_tension_curls_it_more():
    rng = np.random.default_rng(0)
    mirror = np.array([1.0, 1.0, 1.0])
    calm = hands.rest_channels(300, 0.2, "neutral", rng)
    assert 15.0 < _mean_angle_deg(hands.finger_poses(calm, mirror)) < 35.0  # a real hand: about 23 degrees
    angry = hands.rest_channels(300, 0.2, "anger", np.random.default_rng(0))
    assert _mean_angle_deg(hands.finger_poses(angry, mirror)) > _mean_angle_deg(hands.finger_poses(calm, mirror)) + 5
    assert calm[:, 0].std() > 0.02  # never quite still


def test_the_right_hand_mirrors_the_left():
    channels = hands.rest_channels(10, 0.2, "neutral", np.random.default_rng(1))
    left = hands.finger_poses(channels, np.array([1.0, 1.0, 1.0]))
    right = hands.finger_poses(channels, np.array([1.0, -1.0, -1.0]))
    assert left.shape == (10, 15, 3)
    np.testing.assert_allclose(right[..., 0], left[..., 0])
    np.testing.assert_allclose(right[..., 1:], -left[..., 1:])


def test_strokes_take_the_emotions_shapes():
    rng = np.random.default_rng(2)
    alike = np.ones(len(hands.SHAPES))
    sad = [hands.stroke_shape(rng, "sadness", alike) for _ in range(400)]
    angry = [hands.stroke_shape(rng, "anger", alike) for _ in range(400)]
    assert sad.count("limp") / 400 > 0.6 and "point" not in sad
    assert angry.count("fist") / 400 > 0.35 and "limp" not in angry
    habits = np.array([1.0, 20.0, 1.0, 1.0, 1.0])  # a speaker who points
    assert [hands.stroke_shape(rng, "neutral", habits) for _ in range(200)].count("point") > 100
    channels = hands.rest_channels(60, 0.2, "neutral", rng)
    bump = np.exp(-0.5 * ((np.arange(60) - 30) / 5.0) ** 2)
    before = channels.copy()
    hands.add_shape(channels, "fist", bump)
    assert np.allclose(channels[0], before[0], atol=1e-3)  # away from the stroke: unchanged
    assert channels[30, :4].mean() == pytest.approx(np.mean(hands.HAND_SHAPES["fist"][:4]), abs=0.15)


def test_the_body_turns_between_listeners_only_where_a_phrase_starts():
    rng = np.random.default_rng(3)
    active = np.zeros(900, bool)
    for start in range(30, 900, 150):  # a phrase every 5 s, 3 s long
        active[start: start + 90] = True
    yaw = listener_yaw(active, rng)
    assert np.abs(yaw).max() <= LISTENER_YAW + 1e-9
    assert np.degrees(yaw.std()) > 2.0  # it turns (a person: about 5 degrees)
    steady = np.abs(np.diff(yaw)) < 1e-4
    starts = np.flatnonzero(np.diff(active.astype(int)) == 1) + 1
    moving = np.flatnonzero(~steady)
    assert all(np.abs(starts - m).min() <= 45 for m in moving)  # turns happen around phrase starts
