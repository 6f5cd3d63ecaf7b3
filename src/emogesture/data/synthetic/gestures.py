"""Procedural SMPL-X upper-body gestures timed by speech (docs/design.md, 'Synthetic corpus').

The motion is built from named control channels (radians, per frame) and mapped onto SMPL-X
local axis-angle rotations (Y-up, facing +Z, left arm along +X at rest):

* posture = rest pose (arms hanging: shoulders ±``ARM_DOWN`` rad about Z, elbows slightly bent) + emotion
  posture + speaker rest offsets + per-take jitter, drifting slowly;
* a "gesture space" lift of the hands while speaking (smoothed voice activity), back to the hanging
  rest in pauses;
* strokes on the strongest voiced onsets (stressed syllables, phrase accents), about one every
  ``STROKE_GAP`` s scaled by the emotion's and speaker's rate, some left out (``P_REST``: the hands
  rest or hold), each apex a little off its onset (``APEX_JITTER``) and sometimes held
  (``MAX_HOLD``): an asymmetric Gaussian rise-apex-return of shoulder, elbow, wrist, collar,
  torso-twist and head-nod channels; most strokes bend the elbow (beats) with the forearm turned in
  toward the midline, some raise the arm and open the elbow (``P_REACH``: an arm reaching out), some
  bring both hands together in front of the body (``P_TOGETHER``); amplitude, width and rate from
  emotion × speaker × jitter, hands from the speaker's handedness;
* travel between places in the gesture space (``TRAVEL_*``): while the speaker talks, each hand moves to a new
  place every fraction of a second to a second (elbow bend, the upper arm, the shoulder coming up and forward),
  each move a minimum-jerk path at a bounded rate and not locked to the syllables, as preparations,
  retractions and a hand moving to where the next idea sits are in real conversation;
* hands (:mod:`.hands`): loosely curled at rest, each stroke forming a hand shape of the emotion and
  the speaker's habits (open, point, grip, fist, limp);
* a body that turns and leans: the root turns slowly toward one of a few imagined listeners, switching
  at phrase starts (``LISTENER_YAW``), shifts its weight, and shares the posture's lean (leaning in
  while talking);
* an idle layer that never stops (``IDLE``): band-limited sway, twist and lean of each spine joint,
  head and neck movement, collar movement, and arm and wrist movement scaled by the take's amplitude,
  so no joint is frozen (corpus version 2 moved its torso at a tenth of real speed: docs/design.md, 'How real
  motion moves');
* breathing, a tremor for fear, the jaw opening with the speech energy.

Measured with ``emogesture motion-stats`` against real conversational motion capture: see
``experiments/README.md``.

Mirror rule: the right side uses the left side's channels with the Y and Z rotation components
negated (a reflection through the body's mid-plane). Lower-body joints stay at zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial.transform import Rotation

from emogesture.audio import TARGET_SAMPLE_RATE, detect_onsets, frame_energy, onset_strength
from emogesture.data.synthetic import hands
from emogesture.data.synthetic.factors import POSTURE_KEYS, Emotion, Speaker, TakeJitter, smooth_noise
from emogesture.types import FPS, NUM_JOINTS

ARM_DOWN = 1.30  # rad about Z that brings the T-pose arms down beside the body (hands near the thighs)
REST = dict(flex=0.0, abduct=0.0, elbow=0.2)
MAX_ADDUCTION = 0.0  # rad the hanging arm may come closer to the body than at rest
MAX_ABDUCTION, MAX_FLEX = 0.8, 1.25  # rad: how far the arm may rise sideways and forwards (hands below the head)
MAX_ELBOW = 1.9  # rad: the most the elbow bends
MAX_ELBOW_SPEED = 6.5  # rad/s the elbow turns at most
RAISED_REACH = 1.6  # rad less elbow bend per rad the arm rises beyond 0.7 rad forward or 0.4 rad sideways (hands below the head)
STROKE_WIDTH = 0.13  # s, rise half-width of a neutral stroke (return is 1.4× longer)
STROKE_GAP = 0.38  # s, minimum spacing of neutral strokes
P_REST = 0.1  # share of chosen stroke times left out: the hands rest or hold
APEX_JITTER = 0.11  # s, sd of a stroke's apex about its onset
MAX_HOLD = 0.3  # s, longest hold at a stroke's apex
P_TOGETHER = 0.12  # share of strokes that bring both hands together in front of the body
INWARD_TALK = 0.25  # rad the forearms turn in toward the midline while talking (times the elbow's bend)
LISTENER_YAW = 0.24  # rad: the imagined listeners sit within this turn of straight ahead
P_TURN = 0.5  # chance that a phrase is addressed to another listener
ROOT_LEAN = 0.3  # share of the posture's lean taken by the root (the spine takes the rest)
STROKE_AMPLITUDE = 1.1  # rad scale of a neutral stroke
MAX_STROKE = 1.8  # rad: the largest stroke
MAX_HAND_SPEED = 3.2  # m/s: a stroke's rise is slowed until the hand's fastest travel stays below this
FOREARM, ARM = 0.28, 0.55  # m: the hand's distance from the elbow and from the shoulder (lever of each channel)
P_REACH = 0.3  # share of strokes that open the elbow (an arm reaching out) instead of bending it
STROKE_GAIN = dict(elbow=1.6, flex=0.68, abduct=0.68)  # a stroke's extent per channel beyond its direction (the forearm carries the beat)
TALK_BEND = 0.5  # rad more elbow bend while talking (times the hand's share of the lift)
# travel between places in the gesture space, not locked to syllables (preparations, retractions, a hand
# moving to where the next idea sits): a new place every TRAVEL_EVERY s, reached in TRAVEL_MOVE s (both
# divided by the take's speed), each channel's place drawn about the talking posture with sd TRAVEL_SPREAD rad
TRAVEL_EVERY = (0.2, 1.0)
TRAVEL_MOVE = (0.35, 0.7)
TRAVEL_SPREAD = dict(elbow=0.8, flex=0.08, abduct=0.06, collar_up=0.05, collar_fwd=0.12)
TRAVEL_RATE = dict(elbow=3.0, flex=1.0, abduct=1.0, collar_up=0.5, collar_fwd=0.5)  # rad/s
# the idle layer (never still): (amplitude rad, smoothing s) of band-limited noise per joint group
IDLE = dict(spine=(0.035, 0.3), neck=(0.05, 0.25), collar=(0.035, 0.2), wrist=(0.1, 0.3), arm=(0.13, 0.35))
SPINE, NECK, HEAD, JAW = (3, 6, 9), 12, 15, 22
COLLAR, SHOULDER, ELBOW, WRIST = (13, 14), (16, 17), (18, 19), (20, 21)
HAND = (tuple(range(25, 40)), tuple(range(40, 55)))  # the 15 finger joints of each hand


@dataclass(frozen=True)
class Stroke:
    """One gesture stroke: apex time, extent (s), strength score 0-1 and hand(s) 'left'/'right'/'both'."""

    apex: float
    start: float
    end: float
    score: float
    hand: str


def pick_strokes(onsets: np.ndarray, strength: np.ndarray, active: np.ndarray, min_gap: float,
                 rng: np.random.Generator) -> np.ndarray:
    """Greedy choice of stroke times among voiced onsets, strongest first, at least ``min_gap`` apart."""
    keep = active[np.clip(np.round(onsets * FPS).astype(int), 0, len(active) - 1)]
    cand, score = onsets[keep], strength[keep] * rng.uniform(0.6, 1.0, keep.sum())
    chosen: list[float] = []
    for i in np.argsort(-score, kind="stable"):
        if all(abs(cand[i] - c) >= min_gap for c in chosen):
            chosen.append(float(cand[i]))
    return np.sort(np.asarray(chosen))


def _hand_weights(speaker: Speaker, asymmetry: float) -> tuple[float, float]:
    """(left, right) share of the gesture-space lift."""
    weak = 0.45 * (1.0 - asymmetry)
    if speaker.handedness == "both":
        return 1.0, 1.0 - 0.6 * asymmetry
    return (weak, 1.0) if speaker.handedness == "right" else (1.0, weak)


def gesture_space_travel(t: np.ndarray, lift: np.ndarray, amp: float, speed: float,
                         rng: np.random.Generator) -> dict[str, np.ndarray]:
    """One hand's travel between places in the gesture space: offsets ``[T]`` (rad) of the ``TRAVEL_SPREAD``
    channels, each move a minimum-jerk path, times ``lift`` (the hands travel while the speaker talks)."""
    channels = {k: np.zeros(len(t)) for k in TRAVEL_SPREAD}
    place = dict.fromkeys(TRAVEL_SPREAD, 0.0)
    start = rng.uniform(0.0, TRAVEL_EVERY[1]) / speed
    end = t[-1] if len(t) else 0.0
    while start < end:
        new = {k: rng.normal(0.0, sd) * amp ** 0.5 for k, sd in TRAVEL_SPREAD.items()}
        for k in ("collar_up", "collar_fwd"):  # the shoulder comes up and forward with the hand, never down or
            new[k] = abs(new[k])  # back (a lowered shoulder would carry the hanging arm into the hip)
        # a long way takes its time: no channel turns faster than TRAVEL_RATE on average over the move
        move = max(rng.uniform(*TRAVEL_MOVE) / speed, *(abs(new[k] - place[k]) / TRAVEL_RATE[k] for k in new))
        tau = np.clip((t - start) / move, 0.0, 1.0)
        ramp = tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau ** 2)
        for k in TRAVEL_SPREAD:
            channels[k] += (new[k] - place[k]) * ramp
        place = new
        start += move + rng.uniform(*TRAVEL_EVERY) / speed
    return {k: v * lift for k, v in channels.items()}


def listener_yaw(active: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The root's slow turn ``[T]`` (rad) toward one of three imagined listeners, another one at some phrase
    starts (where ``active`` speech begins), smoothed into a turn of about a second."""
    listeners = rng.uniform(-LISTENER_YAW, LISTENER_YAW, 3)
    yaw = np.empty(len(active))
    current, last = int(rng.integers(3)), 0
    for start in np.flatnonzero(np.diff(active.astype(int)) == 1) + 1:
        yaw[last:start] = listeners[current]
        if rng.uniform() < P_TURN:
            current = int((current + rng.integers(1, 3)) % 3)
        last = start
    yaw[last:] = listeners[current]
    return gaussian_filter1d(yaw, 0.5 * FPS, mode="nearest")


def make_motion(wave: np.ndarray, emotion: Emotion, speaker: Speaker, jitter: TakeJitter,
                rng: np.random.Generator, sample_rate: int = TARGET_SAMPLE_RATE,
                hand_habits: np.ndarray | None = None) -> tuple[np.ndarray, list[Stroke]]:
    """Gestures for one take: ``(poses [T, 55, 3] float32 axis-angle, strokes)``, ``T = round(s × 30)``.
    ``hand_habits``: the speaker's liking for each hand shape (:func:`.hands.speaker_habits`; default alike)."""
    habits = np.ones(len(hands.SHAPES)) if hand_habits is None else np.asarray(hand_habits, np.float64)
    energy = frame_energy(wave, sample_rate, FPS).astype(np.float64)
    n = len(energy)
    t = np.arange(n) / FPS
    em, sm = emotion.motion, speaker.motion
    amp = em.amplitude * sm.amplitude * jitter.amplitude
    speed = em.speed * sm.speed * jitter.speed / speaker.smoothness
    level = energy / (np.percentile(energy, 95) + 1e-9)
    active = gaussian_filter1d((level > 0.15).astype(float), 3) > 0.5
    lift = gaussian_filter1d(active.astype(float), 0.45 * FPS)  # hands up while talking, down in pauses

    # Channels: posture per side (L, R) and body.
    post = {k: em.posture.get(k, 0.0) + sm.posture.get(k, 0.0) + jitter.posture[k] for k in POSTURE_KEYS}
    drift = smooth_noise(rng, n, 1.5 * FPS, len(POSTURE_KEYS)) * 0.035
    body = {k: post[k] + drift[:, i] for i, k in enumerate(POSTURE_KEYS)}
    breath_f = rng.uniform(0.2, 0.3)
    breath = np.sin(2 * np.pi * breath_f * t + rng.uniform(0, 2 * np.pi))
    body["lean"] = body["lean"] + 0.012 * breath
    body["shrug"] = body["shrug"] + 0.012 * breath
    body["head_turn"] = body["head_turn"] + 0.06 * smooth_noise(rng, n, 1.0 * FPS)[:, 0]
    weights = _hand_weights(speaker, em.asymmetry)
    arm_keys = ("flex", "abduct", "elbow", "wflex", "wdev", "twist", "inward")
    arms = [{k: np.zeros(n) for k in (*arm_keys, "collar_up", "collar_fwd")} for _ in range(2)]
    fingers = [hands.rest_channels(n, speaker.finger_curl, emotion.name, rng) for _ in range(2)]
    root = dict(yaw=listener_yaw(active, rng) + 0.02 * smooth_noise(rng, n, 1.0 * FPS)[:, 0],
                roll=0.015 * smooth_noise(rng, n, 2.0 * FPS)[:, 0],  # weight shifts
                pitch=0.03 * lift * amp ** 0.5)  # leaning in while talking
    for side in range(2):
        a = arms[side]
        noise = smooth_noise(rng, n, IDLE["arm"][1] * FPS, len(arm_keys)) * IDLE["arm"][0] * np.sqrt(amp)
        wrist_noise = smooth_noise(rng, n, IDLE["wrist"][1] * FPS, 3) * IDLE["wrist"][0] * np.sqrt(amp)
        noise[:, 3:6] += wrist_noise
        for i, k in enumerate(arm_keys):
            a[k] += noise[:, i]
        a["flex"] += REST["flex"] + body["flex"] + 0.1 * weights[side] * lift * amp ** 0.5
        a["abduct"] += REST["abduct"] + body["abduct"] + 0.05 * weights[side] * lift * amp
        a["elbow"] += REST["elbow"] + body["elbow"] + TALK_BEND * weights[side] * lift * amp ** 0.5
        a["inward"] += INWARD_TALK * weights[side] * lift
        for k, v in gesture_space_travel(t, lift, amp * weights[side], speed, rng).items():
            a[k] += v
        if em.tremor:
            shake = smooth_noise(rng, n, 1.0, 3) - smooth_noise(rng, n, 4.0, 3) * 0.5
            a["wflex"] += em.tremor * 2 * shake[:, 0]
            a["elbow"] += em.tremor * shake[:, 1]
            a["flex"] += em.tremor * 0.5 * shake[:, 2]

    # Strokes at onsets.
    envelope = onset_strength(wave, sample_rate)
    onsets = detect_onsets(wave, sample_rate, envelope=envelope)
    strength = envelope[np.clip(np.round(onsets * sample_rate / 512).astype(int), 0, len(envelope) - 1)]
    strength = strength / (strength.max() + 1e-9) if strength.size else strength
    gap = STROKE_GAP / (em.rate * sm.rate * jitter.rate)
    apexes = pick_strokes(onsets, strength, active, gap, rng)
    strokes: list[Stroke] = []
    rise = STROKE_WIDTH / speed
    fall = 1.4 * rise
    p_both = (0.6 if speaker.handedness == "both" else 0.2) * (1 - em.asymmetry)
    p_weak = 0.12 * (1 - em.asymmetry)
    dominant = 0 if speaker.handedness == "left" else 1
    last = -np.inf  # the previous stroke's apex: a jittered apex keeps half the spacing after it (two strokes
    for apex in apexes:  # landing on one another would move the hand at twice a stroke's capped speed)
        rest, hold = rng.uniform() < P_REST, rng.uniform(0.0, MAX_HOLD) * (rng.uniform() < 0.4)
        apex = float(np.clip(max(apex + rng.normal(0.0, APEX_JITTER), last + 0.5 * gap), 0.0, t[-1]))
        s = float(np.interp(apex, onsets, strength)) if onsets.size else 1.0
        a_k = min(STROKE_AMPLITUDE * amp * (0.55 + 0.45 * s) * float(np.exp(rng.normal(0.0, 0.25))), MAX_STROKE)
        u = rng.uniform()
        sides = (0, 1) if u < p_both else ((1 - dominant,) if u < p_both + p_weak else (dominant,))
        kind = rng.uniform()
        slow = 1.0
        if kind < P_TOGETHER:  # both hands come together in front of the body, slowly, and stay a moment
            sides, hold, slow = (0, 1), hold + 0.3, 1.6
            direction = dict(elbow=rng.uniform(0.7, 1.0), flex=rng.uniform(0.35, 0.6), abduct=rng.normal(0, 0.1),
                             wflex=rng.normal(0, 0.2), wdev=rng.normal(0, 0.1), twist=rng.normal(0, 0.2),
                             inward=rng.uniform(0.8, 1.1))
        elif kind < P_TOGETHER + P_REACH:  # reach out: the arm rises forward and the elbow opens
            direction = dict(elbow=-rng.uniform(0.2, 0.5), flex=rng.uniform(0.6, 1.0), abduct=rng.normal(0, 0.4),
                             wflex=rng.normal(0, 0.35), wdev=rng.normal(0, 0.2), twist=rng.normal(0, 0.35),
                             inward=rng.normal(0, 0.1))
        else:  # a beat in front of the body, the forearm turned in
            direction = dict(elbow=rng.uniform(0.5, 1.0), flex=rng.uniform(0.0, 0.5), abduct=rng.normal(0, 0.3),
                             wflex=rng.normal(0, 0.35), wdev=rng.normal(0, 0.2), twist=rng.normal(0, 0.35),
                             inward=rng.uniform(0.0, 0.3))
        # a large stroke takes its time: a Gaussian rise of extent d (m) over half-width w peaks at 0.61 d / w
        reach = a_k * (FOREARM * STROKE_GAIN["elbow"] * abs(direction["elbow"])
                       + ARM * STROKE_GAIN["flex"] * float(np.hypot(direction["flex"], direction["abduct"])))
        floor = 0.61 * reach / MAX_HAND_SPEED
        w = slow * np.where(t < apex, max(rise, floor), max(fall, 1.4 * floor))
        bump = np.exp(-0.5 * (np.maximum(t - apex - hold, 0.0) + np.minimum(t - apex, 0.0)) ** 2 / w ** 2)
        shape = "open" if kind >= P_TOGETHER and kind < P_TOGETHER + P_REACH and rng.uniform() < 0.6 else \
            hands.stroke_shape(rng, emotion.name, habits)
        if rest:  # a chosen stroke time left out: no stroke (the draws above keep the take's others alike)
            continue
        last = apex
        shape_bump = np.exp(-0.5 * (np.maximum(t - apex - hold, 0.0) / (2 * fall)
                                    + np.minimum(t - apex + 0.05, 0.0) / (1.5 * rise)) ** 2)
        for side in sides:
            for k, v in direction.items():
                arms[side][k] += a_k * v * STROKE_GAIN.get(k, 1.0) * bump
            hands.add_shape(fingers[side], shape, shape_bump, float(np.clip(a_k / STROKE_AMPLITUDE, 0.3, 1.0)))
        body["head_pitch"] += 0.12 * a_k * rng.uniform(0.0, 1.0) * bump
        body["lean"] += 0.04 * a_k * bump
        body["shrug"] += 0.08 * a_k * rng.uniform(0.3, 1.0) * bump  # the collars take part in the stroke
        body["twist"] += 0.08 * a_k * rng.normal(0.0, 1.0) * bump
        score = float(np.clip(1.0 - np.exp(-a_k / 0.35), 0.0, 1.0))
        hand = "both" if len(sides) == 2 else ("left", "right")[sides[0]]
        strokes.append(Stroke(apex, max(0.0, apex - 2 * rise), min(t[-1] if n else 0.0, apex + hold + 2 * fall),
                              round(score, 3), hand))
    return _to_poses(body, arms, fingers, root, energy, rng), strokes


def rate_limited(x: np.ndarray, step: float) -> np.ndarray:
    """``x`` ``[T]`` followed with at most ``step`` change per frame."""
    out = np.empty_like(x)
    out[0] = x[0]
    for i in range(1, len(x)):
        out[i] = out[i - 1] + min(max(x[i] - out[i - 1], -step), step)
    return out


def _to_poses(body: dict, arms: list[dict], fingers: list[np.ndarray], root: dict, energy: np.ndarray,
              rng: np.random.Generator) -> np.ndarray:
    """Map the control channels onto SMPL-X local axis-angle rotations ``[T, 55, 3]``."""
    n = len(energy)
    poses = np.zeros((n, NUM_JOINTS, 3))
    # the root: turned toward a listener, sharing the posture's lean, shifting its weight
    poses[:, 0] = np.stack([ROOT_LEAN * body["lean"] + root["pitch"], root["yaw"], root["roll"]], axis=1)
    idle = {k: smooth_noise(rng, n, sigma * FPS, 3) * a for k, (a, sigma) in IDLE.items()}
    for k, j in enumerate(SPINE):  # sway, twist and lean that never stop, strongest low in the spine
        poses[:, j] = np.stack([(1.0 - ROOT_LEAN) * body["lean"], body["twist"], body["side"]], axis=1) / 3.0
        # (lean, twist, side): little side bend, which would carry the chest into a hanging arm
        poses[:, j] += (smooth_noise(rng, n, IDLE["spine"][1] * FPS, 3) * IDLE["spine"][0] * (1.0 - 0.25 * k)
                        * np.array([1.0, 1.0, 0.3]))
    poses[:, NECK] = np.stack([0.4 * body["head_pitch"], 0.5 * body["head_turn"], 0.3 * body["head_tilt"]], 1)
    poses[:, HEAD] = np.stack([0.6 * body["head_pitch"], 0.5 * body["head_turn"], 0.7 * body["head_tilt"]], 1)
    poses[:, NECK] += idle["neck"]
    poses[:, HEAD] += smooth_noise(rng, n, IDLE["neck"][1] * FPS, 3) * IDLE["neck"][0]
    jaw = np.clip(gaussian_filter1d(energy / (np.percentile(energy, 95) + 1e-9), 1.0), 0.0, 1.3)
    poses[:, JAW, 0] = 0.12 * jaw
    mirror = (np.array([1.0, 1.0, 1.0]), np.array([1.0, -1.0, -1.0]))
    for side in range(2):
        a, m = arms[side], mirror[side]
        # a lowered shoulder (negative shrug) turns the hanging arm inwards as well: together they bring
        # the arm at most MAX_ADDUCTION closer to the body than the rest pose, so the hand stays beside the hips
        # (and a chest bent sideways toward the arm tilts the hanging arm into the hip: the arm opens as much)
        toward = np.maximum(body["side"] if side == 1 else -body["side"], 0.0)
        abduct = np.clip(a["abduct"], -MAX_ADDUCTION - np.minimum(body["shrug"], 0.0) + toward, MAX_ABDUCTION)
        flex = np.clip(a["flex"], -0.3, MAX_FLEX)
        down = Rotation.from_rotvec(np.stack([np.zeros(n), np.zeros(n), -(ARM_DOWN - abduct)], 1))
        forward = Rotation.from_rotvec(np.stack([-flex, np.zeros(n), np.zeros(n)], 1))
        raised = np.maximum(flex - 0.7, 0.0) + np.maximum(abduct - 0.4, 0.0) + a["collar_up"]  # a raised shoulder too
        cap = MAX_ELBOW - RAISED_REACH * raised  # approached softly (a hard clip snaps the forearm open)
        bend = rate_limited(np.maximum(-0.1 * np.logaddexp(-a["elbow"] / 0.1, -cap / 0.1), 0.05),
                            MAX_ELBOW_SPEED / FPS)
        # the upper arm turned about its own axis: a bent forearm swings in toward the midline (a straight
        # arm hardly moves, so the turn follows the elbow's bend as the elbow makes it)
        inward = (np.clip(a["inward"], -0.2, 1.1) * np.clip((bend - 0.3) / 0.9, 0.0, 1.0)
                  * np.clip(flex / 0.3, 0.0, 1.0))  # and the arm's reach forward, so the hand stays in front
        turn = Rotation.from_rotvec(np.stack([inward, np.zeros(n), np.zeros(n)], 1))
        poses[:, SHOULDER[side]] = (forward * down * turn).as_rotvec() * m
        collar = smooth_noise(rng, n, IDLE["collar"][1] * FPS, 3) * IDLE["collar"][0]
        poses[:, COLLAR[side]] = (np.stack([np.zeros(n), -a["collar_fwd"], body["shrug"] + a["collar_up"]], 1)
                                  + collar) * m
        poses[:, ELBOW[side]] = np.stack([np.zeros(n), -bend, np.zeros(n)], 1) * m
        poses[:, WRIST[side]] = np.stack([a["twist"], 0.5 * a["wdev"], -0.6 * a["wflex"]], 1) * m
        poses[:, list(HAND[side])] = hands.finger_poses(fingers[side], m)
    return poses.astype(np.float32)
