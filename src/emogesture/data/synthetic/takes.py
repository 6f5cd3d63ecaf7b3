"""One take of the synthetic corpus: plan, build (speech + gestures + annotations), validate.

A take's four files are each written atomically (temporary name, then ``os.replace``) in the order
wav, TextGrid, sem, npz; :func:`check_take` accepts a take only when all four exist, parse, and
agree on the length, so an interrupted or damaged take is rebuilt.
"""

from __future__ import annotations

import os
import secrets
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import soundfile as sf

from emogesture.data.beat import EMOTIONS, format_take_name
from emogesture.data.synthetic.factors import (
    EMOTION_FACTORS,
    combine_prosody,
    make_jitter,
    make_speaker,
    scale_prosody,
    words_needed,
)
from emogesture.data.synthetic.gestures import Stroke, make_motion
from emogesture.data.synthetic.hands import speaker_habits
from emogesture.data.synthetic.speech import (
    SAMPLE_RATE,
    run_engine,
    shape_audio,
    speech_segments,
    textgrid,
    word_timings,
)
from emogesture.data.synthetic.text import make_text, sentences_for_words
from emogesture.errors import EmogestureError
from emogesture.motion import save_smplx_npz
from emogesture.types import FPS, NUM_JOINTS, SMPLXSequence

SUBDIRS = {"npz": "smplxflame_30", "wav": "wave16k", "textgrid": "textgrid", "sem": "sem"}
SUFFIXES = {"npz": ".npz", "wav": ".wav", "textgrid": ".TextGrid", "sem": ".txt"}
MAX_EXTRA_SENTENCES = 12


@dataclass(frozen=True)
class TakePlan:
    """Everything a worker needs to build one take (factors are re-derived from the seed)."""

    speaker_id: int
    take: int  # BEAT take id, inside the emotion's range
    emotion: int  # index into EMOTIONS
    text_index: int
    seed: int
    min_seconds: float
    engines: tuple[str, ...]
    emotion_prosody_scale: float  # see CorpusConfig

    @property
    def name(self) -> str:
        return format_take_name(self.speaker_id, self.take)


def take_paths(out: Path, name: str) -> dict[str, Path]:
    """The four files of take ``name`` under corpus root ``out``."""
    return {k: out / SUBDIRS[k] / f"{name}{SUFFIXES[k]}" for k in SUBDIRS}


def base_sentences(plan: TakePlan) -> int:
    """Sentences of the text's stream every speaker of this text starts from."""
    emotion = EMOTIONS[plan.emotion]
    words = words_needed(plan.min_seconds, emotion, plan.emotion_prosody_scale)
    return sentences_for_words(plan.seed, emotion, plan.text_index, words)


def _replace_atomic(path: Path, write) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def sem_lines(strokes: list[Stroke], words: list[tuple[float, float, str]]) -> str:
    """BEAT ``sem`` rows, one per stroke: ``beat``, start, end, duration, score, keywords (the words
    spoken within 0.15 s of the stroke's apex)."""
    rows = []
    for s in strokes:
        near = [w for a, b, w in words if a <= s.apex + 0.15 and b >= s.apex - 0.15]
        rows.append(f"beat\t{s.start:.3f}\t{s.end:.3f}\t{s.end - s.start:.3f}\t{s.score:.3f}\t{' '.join(near)}")
    return "".join(r + "\n" for r in rows)


def build_take(out: Path, plan: TakePlan) -> str:
    """Synthesise, animate and write one take; returns its name. Deterministic in ``plan``."""
    emotion_name = EMOTIONS[plan.emotion]
    emotion = EMOTION_FACTORS[emotion_name]
    speaker = make_speaker(plan.seed, plan.speaker_id, plan.engines)
    jitter = make_jitter(plan.seed, plan.speaker_id, plan.take)
    emotion_prosody = scale_prosody(emotion.prosody, plan.emotion_prosody_scale)
    prosody = combine_prosody(speaker.prosody, emotion_prosody, jitter.prosody)
    first = base_sentences(plan)
    with tempfile.TemporaryDirectory(prefix="emogesture-tts-") as tmp:
        for count in range(first, first + MAX_EXTRA_SENTENCES + 1):  # lengthen a take that came out short
            text = make_text(plan.seed, emotion_name, plan.text_index, count)
            raw = run_engine(text, speaker.voice, prosody, speaker.timbre, Path(tmp))
            if len(raw) >= plan.min_seconds * SAMPLE_RATE:
                break
        else:
            raise EmogestureError(f"{plan.name}: speech stays shorter than {plan.min_seconds} s")
    audio, clean = shape_audio(raw, prosody, np.random.default_rng([plan.seed, 404, plan.speaker_id, plan.take]))
    duration = len(audio) / SAMPLE_RATE
    words = word_timings(text, speech_segments(clean))
    poses, strokes = make_motion(audio, emotion, speaker, jitter,
                                 np.random.default_rng([plan.seed, 303, plan.speaker_id, plan.take]),
                                 hand_habits=speaker_habits(plan.seed, plan.speaker_id))
    paths = take_paths(out, plan.name)
    for p in paths.values():
        p.parent.mkdir(parents=True, exist_ok=True)
    _replace_atomic(paths["wav"], lambda p: sf.write(str(p), audio, SAMPLE_RATE, subtype="PCM_16", format="WAV"))
    _replace_atomic(paths["textgrid"], lambda p: p.write_text(textgrid(words, duration), encoding="utf-8"))
    _replace_atomic(paths["sem"], lambda p: p.write_text(sem_lines(strokes, words), encoding="utf-8"))
    betas = np.zeros(300, np.float32)
    betas[:10] = speaker.betas
    seq = SMPLXSequence(poses=poses, trans=np.zeros((len(poses), 3), np.float32), betas=betas, fps=FPS)
    save_smplx_npz(seq, paths["npz"], overwrite=True)
    return plan.name


def check_take(out: Path, name: str) -> float | None:
    """Duration (s) of a complete, consistent take, or None if any file is missing or damaged."""
    paths = take_paths(out, name)
    try:
        if not all(p.is_file() for p in paths.values()):
            return None
        info = sf.info(str(paths["wav"]))
        if (info.samplerate != SAMPLE_RATE or info.channels != 1 or info.subtype != "PCM_16"
                or info.frames <= 0):
            return None
        with np.load(paths["npz"], allow_pickle=False) as data:
            poses = data["poses"]
            if poses.ndim != 2 or poses.shape[1] != NUM_JOINTS * 3 or not np.isfinite(poses).all():
                return None
            if poses.shape[0] != int(round(info.frames / SAMPLE_RATE * FPS)):
                return None
        if not paths["textgrid"].read_text(encoding="utf-8").startswith('File type = "ooTextFile"'):
            return None
        for line in paths["sem"].read_text(encoding="utf-8").splitlines():
            if len(line.split("\t")) != 6:
                return None
        return info.frames / SAMPLE_RATE
    except Exception:  # any parse failure means "rebuild it"
        return None
