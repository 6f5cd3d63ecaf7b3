"""Real recorded speech for checks (never for training): what a user gives the tool.

No emotion-labelled real speech can be had here, but real recordings can, from two Debian packages:

- ``pocketsphinx-testdata`` (BSD-2) holds about 47 s of 16-kHz speech — five consecutive clips of a LibriVox
  volunteer reading *Sense and Sensibility* (public domain), five clips of a man reading out card names, and
  three short CMU test utterances. Its TIDIGITS clip is LDC data and is left out.
- ``asterisk-core-sounds-en-g722`` (CC BY-SA 3.0) holds the telephone-system prompts of the Asterisk PBX,
  recorded in a studio by a professional voice, Allison Smith, at 16 kHz (G.722); three of its longest
  prompts are used (about 67 s).

Every recording is read speech with no acted emotion: a model should hear it as neutral. (The prompts are
read in a warm, even, customer-service manner, brighter than the readers of the first package.) Either
package may be missing; :func:`real_recordings` returns what is installed.

The clips of a group are joined in their order with 0.3 s of silence between them, so each group is one
recording of a single speaker, as a user would give it.

**Real voices to calibrate on** (:data:`TRAINING_VOICES`, :func:`load_voice`) are other people: the
Asterisk prompts of other languages, each read by its own professional voice, every clip of the voice
joined. Three are studio recordings at 16 kHz (CC BY-SA 3.0; Debian's ``asterisk-core-sounds-{fr,it,ru}-g722``,
about 25 min each); three more are telephone-band recordings at 8 kHz (``asterisk-prompt-es-co``, GPL,
a Colombian Spanish voice, 9 min; ``asterisk-prompt-fr-armelle``, GPL, a French voice, 12 min;
``asterisk-prompt-it-menardi-wav``, CC BY-SA 3.0, an Italian voice, 20 min). They are read without acted
emotion, so the speech model's perception may take each emotion's mean of them given that emotion's corpus
prosody (:func:`training_voice_emotions`; ``calibrate speech --real-voices``). The Mexican Spanish core
prompts are left out: their voice is the English check recording's (Allison Smith), and a check voice is never
trained on. Ten more are volunteers, not professionals,
each reading the letters and syllables of a language aloud for KDE's KLettres (``klettres-data``, GPL-2+;
:data:`LETTER_READERS`, 45 s to 21 min each, their own microphones and rooms).

**Real voices for validation** (:data:`WORD_READERS`): thirteen more volunteers, each reading the names of
KDE's KTuberling stamps in a language (``ktuberling-data``, GPL-2+). Neither trained nor calibrated on, and of
languages none of the letter readers speaks: choices about real voices are made on them, and the check
recordings above are kept for the final score.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
import os
from os import PathLike
from pathlib import Path
import shutil
import subprocess
import tempfile

import numpy as np

from emogesture.audio import TARGET_SAMPLE_RATE as SAMPLE_RATE, load_audio
from emogesture.data.beat import EMOTIONS
from emogesture.data.synthetic.factors import emotion_prosody
from emogesture.data.synthetic.speech import give_prosody
from emogesture.errors import EmogestureError, InputFileError

#: Where Debian's ``pocketsphinx-testdata`` puts its recordings.
POCKETSPHINX_TESTDATA = Path("/usr/share/pocketsphinx/test/data")
#: Where Debian's ``asterisk-core-sounds-en-g722`` puts its English prompts.
ASTERISK_PROMPTS = Path("/usr/share/asterisk/sounds/en_US_f_Allison")
GAP_SECONDS = 0.3
STRETCH_SECONDS = 13  # training_voice_emotions
ASTERISK_SOUNDS = Path("/usr/share/asterisk/sounds")
KLETTRES_SOUNDS = Path("/usr/share/klettres")
KTUBERLING_SOUNDS = Path("/usr/share/ktuberling/sounds")
#: KLettres' languages whose letters a perception may learn from (``klettres-data``, GPL-2+; each read by one
#: volunteer): only those of no KTuberling voice (:data:`WORD_READERS`), so that no reader is in both.
LETTER_READERS = {"ar": "Arabic", "cs": "Czech", "es": "Spanish", "he": "Hebrew", "hu": "Hungarian",
                  "it": "Italian", "ml": "Malayalam", "nl": "Dutch", "pt_BR": "Brazilian Portuguese",
                  "tn": "Setswana"}


@dataclass(frozen=True)
class RealRecording:
    """One real recording: its clips (relative to ``folder``, where Debian's ``package`` installs them), joined
    in order."""

    name: str
    description: str
    clips: tuple[str, ...]
    emotion: str = "neutral"  # read speech, no acted emotion
    folder: Path = POCKETSPHINX_TESTDATA
    package: str = "pocketsphinx-testdata"


RECORDINGS: tuple[RealRecording, ...] = (
    RealRecording("librivox", "a LibriVox volunteer reading Sense and Sensibility (public domain), 5 consecutive "
                  "clips", tuple(f"librivox/sense_and_sensibility_01_austen_64kb-{n:04d}.wav"
                                 for n in (870, 880, 890, 920, 930))),
    RealRecording("cards", "a man reading out card names, 5 clips", tuple(f"cards/{n:03d}.wav" for n in range(1, 6))),
    RealRecording("cmu", "three CMU test utterances ('go forward', numbers, 'something')",
                  ("goforward.raw", "numbers.raw", "something.raw")),
    RealRecording("prompts", "a professional voice (Allison Smith) reading three telephone-system prompts of the "
                  "Asterisk PBX (CC BY-SA 3.0)", ("demo-congrats.g722", "demo-echotest.g722", "demo-moreinfo.g722"),
                  folder=ASTERISK_PROMPTS, package="asterisk-core-sounds-en-g722"),
)


def _read_clip(path: Path) -> np.ndarray:
    if path.suffix == ".raw":  # headerless 16-bit little-endian mono at 16 kHz
        data = np.fromfile(path, "<i2")
        if data.size == 0:
            raise InputFileError(path, "contains no audio samples")
        wave = data.astype(np.float32) / 32768.0
        return wave - wave.mean()
    return load_audio(path, target_sr=SAMPLE_RATE)[0]


def load_real_recording(recording: RealRecording, root: str | PathLike[str] | None = None) -> np.ndarray:
    """The recording's clips (under ``root``; None: the recording's own folder) joined with :data:`GAP_SECONDS`
    of silence -> a 16-kHz waveform ``[N]``."""
    root = Path(root) if root is not None else recording.folder
    waves = []
    for clip in recording.clips:
        path = root / clip
        if not path.is_file():
            raise InputFileError(path, f"not found; install Debian's {recording.package}")
        waves.append(_read_clip(path))
    return join_clips(waves)


def join_clips(waves: list[np.ndarray], min_seconds: float = 0.0) -> np.ndarray:
    """16-kHz clips joined in order with :data:`GAP_SECONDS` of silence between them, the whole repeated
    (with a gap between repeats) until at least ``min_seconds`` long -> ``[N]`` float32."""
    gap = np.zeros(int(GAP_SECONDS * SAMPLE_RATE), np.float32)
    parts: list[np.ndarray] = []
    while not parts or sum(len(p) for p in parts) < min_seconds * SAMPLE_RATE:
        for wave in waves:
            if parts:
                parts.append(gap)
            parts.append(wave)
    return np.concatenate(parts).astype(np.float32)


def real_recordings(root: str | PathLike[str] | None = None) -> list[RealRecording]:
    """The recordings whose clips are all present, each in its own folder (or all under ``root``); raises
    when there are none."""
    def folder(r: RealRecording) -> Path:
        return Path(root) if root is not None else r.folder

    found = [r for r in RECORDINGS if all((folder(r) / c).is_file() for c in r.clips)]
    if not found:
        where = root if root is not None else ", ".join(sorted({str(r.folder) for r in RECORDINGS}))
        packages = " ".join(dict.fromkeys(r.package for r in RECORDINGS))
        raise EmogestureError(f"{where}: no real speech recordings found; install them with "
                              f"`apt-get install {packages}`")
    return found


@dataclass(frozen=True)
class TrainingVoice:
    """A real voice to train on (or, :data:`WORD_READERS`, to validate on): every clip matching ``pattern`` under
    ``folder`` (where Debian's ``package`` installs it)."""

    name: str
    description: str
    folder: Path
    package: str
    pattern: str = "*.g722"
    clip_by_clip: bool = False  # decode each clip alone (clips whose codec settings differ, as Ogg Vorbis's do)


TRAINING_VOICES: dict[str, TrainingVoice] = {v.name: v for v in (
    TrainingVoice("fr_june", "June Wallack, Canadian French telephone prompts", ASTERISK_SOUNDS / "fr_CA_f_June",
                  "asterisk-core-sounds-fr-g722"),
    TrainingVoice("it_carlo", "Carlo, Italian telephone prompts", ASTERISK_SOUNDS / "it_IT_m_Carlo",
                  "asterisk-core-sounds-it-g722"),
    TrainingVoice("ru_ivr", "a Russian telephone-prompt voice", ASTERISK_SOUNDS / "ru_RU_f_IvrvoiceRU",
                  "asterisk-core-sounds-ru-g722"),
    TrainingVoice("es_co", "a Colombian Spanish telephone-prompt voice, 8 kHz", ASTERISK_SOUNDS / "es",
                  "asterisk-prompt-es-co", "*.gsm"),
    TrainingVoice("fr_armelle", "Armelle Desjardins, French telephone prompts, 8 kHz", ASTERISK_SOUNDS / "fr",
                  "asterisk-prompt-fr-armelle", "*.gsm"),
    TrainingVoice("it_menardi", "Paola Dal Zot, Italian telephone prompts, 8 kHz",
                  ASTERISK_SOUNDS / "it_IT_f_Menardi", "asterisk-prompt-it-menardi-wav", "*.wav"),
    *(TrainingVoice(f"letters_{lang.lower()}", f"KLettres' {language} letters and syllables, read aloud",
                    KLETTRES_SOUNDS / lang, "klettres-data", "*.ogg", True) for lang, language in LETTER_READERS.items()),
)}

#: Real people reading word lists: KDE's KTuberling speaks the name of each stamp in the language of its
#: sound theme, each read by its own volunteer (``ktuberling-data``, GPL-2+). Never trained or calibrated on:
#: a validation set of real voices, as the check recordings are its test set. Only themes of at least 50 s.
WORD_READERS: dict[str, TrainingVoice] = {f"words_{lang}": TrainingVoice(
    f"words_{lang}", f"KTuberling's {lang} stamp names, read aloud", KTUBERLING_SOUNDS / lang, "ktuberling-data",
    {"fr": "*.wav", "nn": "*.opus"}.get(lang, "*.ogg"), True)
    for lang in ("ca", "da", "de", "el", "en", "fr", "gl", "lt", "nn", "ru", "sl", "uk", "wa")}


def _decode(clips: list[Path]) -> tuple[bytes, str]:
    """``clips`` decoded by one ffmpeg run and joined -> (16-bit samples at 16 kHz, ffmpeg's error output)."""
    with tempfile.TemporaryDirectory(prefix="emogesture-voice-") as tmp:
        listing = Path(tmp) / "clips.txt"
        listing.write_text("".join(f"file '{c}'\n" for c in clips), encoding="utf-8")
        proc = subprocess.run(["ffmpeg", "-nostdin", "-v", "error", "-f", "concat", "-safe", "0", "-i", str(listing),
                               "-ac", "1", "-ar", str(SAMPLE_RATE), "-f", "s16le", "-"], capture_output=True)
    errors = proc.stderr.decode(errors="replace").strip()
    return (proc.stdout if proc.returncode == 0 else b""), errors


def real_voice(name: str) -> TrainingVoice:
    """The real voice ``name``: a training voice (:data:`TRAINING_VOICES`) or a validation voice
    (:data:`WORD_READERS`)."""
    voices = TRAINING_VOICES | WORD_READERS
    if name not in voices:
        raise EmogestureError(f"real voice {name!r}: unknown; known: {', '.join(voices)}")
    return voices[name]


def load_voice(voice: TrainingVoice) -> np.ndarray:
    """Every clip of ``voice`` in path order, decoded and joined -> a 16-kHz waveform ``[N]`` float32. A clip
    ffmpeg cannot read (two of the Colombian voice's are damaged) is left out, and so are clips of pure silence
    (a ``silence`` folder)."""
    name = voice.name
    clips = sorted(c for c in voice.folder.rglob(voice.pattern) if "silence" not in c.relative_to(voice.folder).parts) \
        if voice.folder.is_dir() else []
    if not clips:
        raise InputFileError(voice.folder, f"no {voice.pattern} clips; install Debian's {voice.package}")
    if shutil.which("ffmpeg") is None:
        raise EmogestureError(f"real voice {name}: ffmpeg is needed to decode its clips")
    if voice.clip_by_clip:  # a clip ffmpeg cannot read is left out; a few ffmpeg processes at a time, in order
        with ThreadPoolExecutor(max_workers=2 * (os.cpu_count() or 1)) as pool:
            decoded = list(pool.map(lambda c: _decode([c]), clips))
        data = b"".join(d for d, _ in decoded)
        if not data:
            raise EmogestureError(f"real voice {name}: ffmpeg could not decode {voice.folder}: "
                                  f"{decoded[-1][1][-200:]}")
        wave = np.frombuffer(data, "<i2").astype(np.float32) / 32768.0
        return wave - wave.mean()
    while True:  # ffmpeg's concat demuxer stops at a clip it cannot open (and exits with 0): leave it out, again
        data, errors = _decode(clips)
        damaged = [c for c in clips if f"'{c}'" in errors]
        if not damaged or len(damaged) == len(clips):
            break
        clips = [c for c in clips if c not in damaged]
    if not data or errors:
        raise EmogestureError(f"real voice {name}: ffmpeg could not decode {voice.folder}: {errors[-200:]}")
    wave = np.frombuffer(data, "<i2").astype(np.float32) / 32768.0
    return wave - wave.mean()


def training_voice_emotions(names: list[str], stretches: int, prosody_scale: float,
                            seed: int = 0) -> tuple[list[np.ndarray], np.ndarray]:
    """The training voices ``names`` speaking every emotion: ``stretches`` stretches of each voice, evenly
    spaced over it, each as recorded (neutral) and given each other emotion's speech prosody as the corpus gives
    it (the factor table at ``prosody_scale``, plus one take's random deviation, drawn from ``seed``;
    :func:`~emogesture.data.synthetic.speech.give_prosody`), then cut to its first 10 s -> 16-kHz waveforms
    ``[160000]`` and their emotions ``[N]`` (indices into ``EMOTIONS``), voice by voice, stretch by stretch,
    emotion by emotion. A stretch is 13 s long, so that the fastest emotion still speaks for 10 s."""
    if stretches < 1:
        raise EmogestureError(f"stretches {stretches}: must be at least 1")
    waves: list[np.ndarray] = []
    labels: list[int] = []
    for v, name in enumerate(names):
        wave = load_voice(real_voice(name))
        seconds = len(wave) // SAMPLE_RATE
        if seconds < STRETCH_SECONDS:
            raise EmogestureError(f"real voice {name}: {seconds} s, too short for a {STRETCH_SECONDS}-s stretch")
        for i, start in enumerate(np.linspace(0, seconds - STRETCH_SECONDS, stretches).astype(int)):
            stretch = wave[start * SAMPLE_RATE:(start + STRETCH_SECONDS) * SAMPLE_RATE]
            for k, emotion in enumerate(EMOTIONS):
                rng = np.random.default_rng([seed, v, i, k])
                spoken = stretch if emotion == "neutral" else give_prosody(
                    stretch, emotion_prosody(emotion, prosody_scale, rng), rng)
                waves.append(np.asarray(spoken[:10 * SAMPLE_RATE], np.float32))
                labels.append(k)
    return waves, np.asarray(labels)
