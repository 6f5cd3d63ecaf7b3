"""The generating factors of the synthetic corpus: voices, speakers, emotions and per-take jitter.

Effects combine additively in their natural units (semitones, log rate, dB, radians) or
multiplicatively for scales, with no speaker × emotion interaction terms, so emotion and speaker
are independent factors. Every take adds its own jitter so neither is recoverable from one number.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d

from emogesture.data.beat import EMOTIONS, SPEAKERS

ENGINES = ("flite", "espeak-ng", "festival")
#: Words per second every voice is normalised to before speaker and emotion rate factors.
BASE_WORDS_PER_SECOND = 2.8


@dataclass(frozen=True)
class Voice:
    """One synthesiser voice.

    ``f0`` is its typical median pitch (Hz) and ``wps`` its words per second at the engine's
    default rate (both measured once on this machine); ``native_pitch`` says whether the engine
    can move the pitch itself (else pitch is moved by resampling, which also shifts formants).
    """

    engine: str
    name: str
    f0: float
    wps: float
    native_pitch: bool = True


#: One voice per BEAT speaker id (1-30), reused cyclically (with further pitch/timbre offsets) beyond
#: the table. The first three speakers already cover all three engines. Two voice families are never
#: given to a speaker of the training actors (``ACTOR_SPLIT``'s val and test speakers only), so a split by
#: speaker holds them out whole: festival's diphone voices (kal at 19, val; ked at 22, test) and espeak-ng's
#: Klatt synthesiser (15 and 17, val; 23, 25, 28 and 29, test).
VOICES: tuple[Voice, ...] = (
    Voice("flite", "rms", 103.0, 2.87, native_pitch=False),
    Voice("espeak-ng", "en-us+m3", 107.0, 3.30),
    Voice("festival", "cmu_us_slt_arctic_hts", 168.0, 2.97, native_pitch=False),
    Voice("flite", "slt", 170.0, 3.17),
    Voice("espeak-ng", "en-us+f2", 198.0, 3.22),
    Voice("flite", "awb", 128.0, 3.23),
    Voice("flite", "kal16", 95.0, 3.30),
    Voice("espeak-ng", "en-gb-scotland+m1", 96.0, 3.31),
    Voice("espeak-ng", "en+f4", 182.0, 3.21),
    Voice("espeak-ng", "en-gb-x-rp+m7", 109.0, 3.25),
    Voice("flite", "kal", 95.0, 3.30),
    Voice("espeak-ng", "en-029+f3", 216.0, 3.30),
    Voice("espeak-ng", "en-us-nyc+m2", 101.0, 3.32),
    Voice("espeak-ng", "en-gb-x-gbclan+m5", 104.0, 3.22),
    Voice("espeak-ng", "en-us+klatt", 104.0, 3.31),
    Voice("espeak-ng", "en-us+Annie", 239.0, 3.37),
    Voice("espeak-ng", "en-gb+klatt3", 103.0, 3.33),
    Voice("espeak-ng", "en-gb-x-rp+adam", 103.0, 3.35),
    Voice("festival", "kal_diphone", 99.0, 2.68, native_pitch=False),
    Voice("espeak-ng", "en-gb-x-gbcwmd+belinda", 229.0, 3.33),
    Voice("espeak-ng", "en+Andy", 97.0, 3.23),
    Voice("festival", "ked_diphone", 99.0, 2.70, native_pitch=False),
    Voice("espeak-ng", "en-us+klatt2", 106.0, 3.31),
    Voice("espeak-ng", "en-gb-scotland+steph", 184.0, 3.46),
    Voice("espeak-ng", "en-029+klatt4", 102.0, 3.38),
    Voice("espeak-ng", "en-us+john", 103.0, 3.33),
    Voice("espeak-ng", "en-us-nyc+linda", 229.0, 3.39),
    Voice("espeak-ng", "en-gb-x-rp+klatt6", 103.0, 3.35),
    Voice("espeak-ng", "en-us+klatt5", 102.0, 3.31),
    Voice("espeak-ng", "en+max", 104.0, 3.33),
)


@dataclass(frozen=True)
class Prosody:
    """Speech factors. ``pitch`` semitones, ``pitch_range`` × F0 spread, ``rate`` × speaking rate,
    ``gain_db`` loudness, ``tilt`` spectral tilt (+ brighter / − duller, vocal effort),
    ``breathiness`` aspiration noise riding on the speech (0-1), ``tremolo`` 5.5 Hz amplitude
    modulation depth (a shaky voice)."""

    pitch: float = 0.0
    pitch_range: float = 1.0
    rate: float = 1.0
    gain_db: float = 0.0
    tilt: float = 0.0
    breathiness: float = 0.0
    tremolo: float = 0.0


#: Posture channels (radians, added to the rest pose): spine lean forward (+) / back (−), spine side
#: bend (+ = to the left), spine twist (+ = turn left), head pitch (+ = down), head tilt, head turn,
#: collar raise (shrug), arm abduction (+ = out), arm forward flexion, elbow bend.
POSTURE_KEYS = ("lean", "side", "twist", "head_pitch", "head_tilt", "head_turn", "shrug", "abduct",
                "flex", "elbow")


@dataclass(frozen=True)
class MotionStyle:
    """Gesture factors: stroke ``amplitude`` and ``speed`` (× sharpness), ``rate`` (× strokes per
    second), ``asymmetry`` (0 = both arms alike, 1 = one arm only), ``tremor`` (rad of fast shake)
    and a ``posture`` offset per POSTURE_KEYS channel."""

    amplitude: float = 1.0
    speed: float = 1.0
    rate: float = 1.0
    asymmetry: float = 0.0
    tremor: float = 0.0
    posture: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Emotion:
    """Prosody plus motion signature of one emotion."""

    name: str
    prosody: Prosody
    motion: MotionStyle


def _emo(name: str, prosody: Prosody, motion: MotionStyle) -> Emotion:
    return Emotion(name, prosody, motion)


EMOTION_FACTORS: dict[str, Emotion] = {e.name: e for e in (
    _emo("neutral", Prosody(), MotionStyle()),
    _emo("happiness", Prosody(pitch=3.0, pitch_range=1.5, rate=1.06, gain_db=3.0, tilt=0.35),
         MotionStyle(amplitude=1.4, speed=1.15, rate=1.2,
                     posture=dict(lean=-0.04, head_pitch=-0.1, abduct=0.16, elbow=0.3, flex=0.1))),
    _emo("anger", Prosody(pitch=1.0, pitch_range=1.2, rate=1.12, gain_db=7.0, tilt=0.8),
         MotionStyle(amplitude=1.5, speed=1.7, rate=1.25,
                     posture=dict(lean=0.14, head_pitch=0.08, shrug=0.05, elbow=0.35, flex=0.12))),
    _emo("sadness", Prosody(pitch=-3.0, pitch_range=0.5, rate=0.78, gain_db=-6.0, tilt=-0.5,
                                breathiness=0.25),
         MotionStyle(amplitude=0.45, speed=0.6, rate=0.6,
                     posture=dict(lean=0.22, head_pitch=0.35, shrug=-0.08, abduct=-0.05, elbow=-0.15))),
    _emo("contempt", Prosody(pitch=-2.0, pitch_range=0.8, rate=0.9, gain_db=-1.5, tilt=0.25),
         MotionStyle(amplitude=0.8, speed=0.85, rate=0.8, asymmetry=0.9,
                     posture=dict(lean=-0.1, side=0.06, head_pitch=-0.14, head_tilt=0.16, twist=0.05))),
    _emo("surprise", Prosody(pitch=5.5, pitch_range=1.8, rate=0.96, gain_db=2.0, tilt=0.1),
         MotionStyle(amplitude=1.2, speed=1.4, rate=1.0,
                     posture=dict(lean=-0.06, head_pitch=-0.12, shrug=0.12, elbow=0.45, abduct=0.08))),
    _emo("fear", Prosody(pitch=3.0, pitch_range=0.6, rate=1.18, gain_db=-3.0, tilt=-0.1,
                             breathiness=0.35, tremolo=0.25),
         MotionStyle(amplitude=0.7, speed=1.3, rate=1.1, tremor=0.012,
                     posture=dict(lean=-0.05, head_pitch=0.06, shrug=0.14, abduct=-0.14, flex=0.3,
                                  elbow=0.65))),
    _emo("disgust", Prosody(pitch=-1.0, pitch_range=0.9, rate=0.88, gain_db=0.5, tilt=-0.35,
                                breathiness=0.1),
         MotionStyle(amplitude=0.8, speed=1.0, rate=0.9, asymmetry=0.4,
                     posture=dict(lean=-0.08, twist=-0.12, head_turn=-0.32, head_tilt=-0.08,
                                  head_pitch=0.04))),
)}
assert tuple(EMOTION_FACTORS) == EMOTIONS


@dataclass(frozen=True)
class Speaker:
    """One synthetic speaker: a voice with prosody offsets, a timbre (resampling factor, ≈1, moving pitch
    and formants together) and a motion style (``handedness`` 'left'/'right'/'both', ``smoothness`` × stroke width,
    ``finger_curl`` rad, ``betas`` the first 10 SMPL-X shape coefficients)."""

    speaker_id: int
    name: str
    voice: Voice
    timbre: float
    prosody: Prosody
    handedness: str
    smoothness: float
    finger_curl: float
    motion: MotionStyle
    betas: tuple[float, ...]

    def to_json(self) -> dict:
        """A JSON-ready dict of every factor."""
        return asdict(self)


def voices_for(engines: tuple[str, ...]) -> tuple[Voice, ...]:
    """The voices of the given engines, in table order."""
    unknown = set(engines) - set(ENGINES)
    if unknown:
        raise ValueError(f"unknown speech engines {sorted(unknown)}; known: {', '.join(ENGINES)}")
    voices = tuple(v for v in VOICES if v.engine in engines)
    if not voices:
        raise ValueError("no speech engine selected")
    return voices


def make_speaker(seed: int, speaker_id: int, engines: tuple[str, ...] = ENGINES) -> Speaker:
    """Draw speaker ``speaker_id``'s factors from ``default_rng([seed, 101, speaker_id])``."""
    voices = voices_for(engines)
    rng = np.random.default_rng([seed, 101, speaker_id])
    u = rng.uniform
    voice = voices[(speaker_id - 1) % len(voices)]
    reuse = (speaker_id - 1) // len(voices)  # a reused voice moves further away in pitch and timbre
    sign = 1.0 if reuse % 2 else -1.0
    pitch = u(-1.5, 1.5) + (sign * (2.0 + 1.5 * reuse) if reuse else 0.0)
    timbre = 1.0 + u(-0.04, 0.04) + (sign * 0.05 if reuse else 0.0)
    prosody = Prosody(pitch=float(pitch), pitch_range=float(np.exp(u(-0.2, 0.2))),
                      rate=float(np.exp(u(-0.1, 0.1))), gain_db=float(u(-1.5, 1.5)),
                      tilt=float(u(-0.15, 0.15)))
    handedness = ("right", "left", "both")[int(rng.choice(3, p=[0.5, 0.25, 0.25]))]
    posture = dict(lean=u(-0.1, 0.1), side=u(-0.05, 0.05), head_pitch=u(-0.1, 0.1), head_tilt=u(-0.1, 0.1),
                   head_turn=u(-0.08, 0.08), shrug=u(-0.05, 0.05), abduct=u(-0.1, 0.12),
                   flex=u(-0.05, 0.12), elbow=u(-0.2, 0.25))
    motion = MotionStyle(amplitude=float(np.exp(u(-0.3, 0.3))), speed=float(np.exp(u(-0.15, 0.15))),
                         rate=float(np.exp(u(-0.3, 0.3))), asymmetry=0.0, tremor=0.0,
                         posture={k: float(v) for k, v in posture.items()})
    betas = tuple(float(b) for b in np.round(rng.normal(0.0, 0.6, 10), 4))
    return Speaker(speaker_id, SPEAKERS[speaker_id], voice, float(timbre), prosody, handedness,
                   float(np.exp(u(-0.2, 0.2))), float(u(0.05, 0.4)), motion, betas)


@dataclass(frozen=True)
class TakeJitter:
    """Per-take random deviations (the 'not trivially recoverable' part)."""

    prosody: Prosody
    amplitude: float
    speed: float
    rate: float
    posture: dict[str, float]


def make_jitter(seed: int, speaker_id: int, take: int) -> TakeJitter:
    """Per-take deviations from ``default_rng([seed, 202, speaker_id, take])``."""
    rng = np.random.default_rng([seed, 202, speaker_id, take])
    n = rng.normal
    prosody = draw_take_prosody(rng)
    posture = {k: float(n(0, 0.04)) for k in POSTURE_KEYS}
    return TakeJitter(prosody, float(np.exp(n(0, 0.15))), float(np.exp(n(0, 0.1))),
                      float(np.exp(n(0, 0.1))), posture)


def draw_take_prosody(rng: np.random.Generator) -> Prosody:
    """One take's random deviation of the speech prosody from its speaker's and emotion's, drawn from ``rng``."""
    n = rng.normal
    return Prosody(pitch=float(n(0, 0.6)), pitch_range=float(np.exp(n(0, 0.12))),
                   rate=float(np.exp(n(0, 0.04))), gain_db=float(n(0, 1.0)), tilt=float(n(0, 0.08)),
                   breathiness=float(abs(n(0, 0.04))))


def emotion_prosody(emotion: str, scale: float, rng: np.random.Generator | None = None) -> Prosody:
    """``emotion``'s speech prosody from the factor table at the corpus's emotion prosody ``scale``; with
    ``rng``, plus one take's random deviation (:func:`draw_take_prosody`) drawn from it."""
    p = scale_prosody(EMOTION_FACTORS[emotion].prosody, scale)
    return p if rng is None else combine_prosody(p, draw_take_prosody(rng))


def combine_prosody(*parts: Prosody) -> Prosody:
    """Sum pitch, gain and tilt; multiply pitch range and rate."""
    return Prosody(
        pitch=sum(p.pitch for p in parts), pitch_range=float(np.prod([p.pitch_range for p in parts])),
        rate=float(np.prod([p.rate for p in parts])), gain_db=sum(p.gain_db for p in parts),
        tilt=sum(p.tilt for p in parts), breathiness=sum(p.breathiness for p in parts),
        tremolo=sum(p.tremolo for p in parts),
    )


def scale_prosody(p: Prosody, scale: float) -> Prosody:
    """``p`` with every effect ``scale`` times as large: additive factors times ``scale``, multiplicative
    ones to the power ``scale`` (1 = unchanged, 0 = neutral)."""
    return Prosody(pitch=p.pitch * scale, pitch_range=float(p.pitch_range ** scale), rate=float(p.rate ** scale),
                   gain_db=p.gain_db * scale, tilt=p.tilt * scale, breathiness=p.breathiness * scale,
                   tremolo=p.tremolo * scale)


def words_needed(min_seconds: float, emotion: str, emotion_prosody_scale: float) -> int:
    """Words a text of ``emotion`` needs so that even its fastest speaker talks ``min_seconds``."""
    rate = EMOTION_FACTORS[emotion].prosody.rate ** emotion_prosody_scale
    fastest = np.exp(0.1) * rate * np.exp(0.1)  # speaker, emotion, jitter
    return int(np.ceil(min_seconds * BASE_WORDS_PER_SECOND * fastest))


def smooth_noise(rng: np.random.Generator, n: int, sigma_frames: float, size: int = 1) -> np.ndarray:
    """Unit-variance low-pass noise ``[n, size]`` (Gaussian-smoothed white noise, σ in frames)."""
    x = gaussian_filter1d(rng.standard_normal((n + 200, size)), sigma_frames, axis=0, mode="wrap")[100:-100]
    return x / (x.std(axis=0, keepdims=True) + 1e-9)
