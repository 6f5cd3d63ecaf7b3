"""Animate a speech recording into files: what ``emogesture generate`` does, callable from Python.

An :class:`AnimationRequest` says what to make: the speech, the output folder, the emotion (the speech's
own, ``auto`` or ``own``, or a label), an optional second recording for the emotion and/or one for the
speaker style, the formats, the seed, the number of samples and of seam candidates. :func:`animate`
turns it into ``<speech><tag>_seed<seed>_<k>.<format>`` for each sample ``k`` and
``<speech><tag>_seed<seed>_perception.json`` in the output folder, where ``<tag>`` names the edit
(``_emotion-<stem>`` or ``_emotion-<label>``, then ``_style-<stem>``, then ``_own``). Every output is
checked before anything is computed, so an existing file without ``overwrite`` leaves nothing new behind.

Example (the bundled model; writes ``out/talk_emotion-happiness_seed0_0.npz`` and the perception report)::

    pipe = GesturePipeline.from_run()
    result = animate(pipe, AnimationRequest("talk.flac", "out", emotion="happiness", formats=("npz",)))
"""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from emogesture.audio import TARGET_SAMPLE_RATE, window_starts
from emogesture.errors import EmogestureError
from emogesture.export import DEFAULT_FORMATS, export_paths, export_sequence, parse_formats
from emogesture.face.phones import recognise_phones, recogniser_installed
from emogesture.fileio import atomic_output, check_output
from emogesture.models.generation import GenerationConfig
from emogesture.motion.rigs import rig_named
from emogesture.pipeline.face import animated_emotions, with_face
from emogesture.pipeline.generate import WINDOW_SECONDS, EditRequest, GesturePipeline, output_stem
from emogesture.pipeline.neutral_reference import MIN_SECONDS, reference_name
from emogesture.pipeline.perception import auto_emotion, heard_by_front_end, perception_of
from emogesture.pipeline.perception_report import PerceivedEmotion
from emogesture.pipeline.postprocess import candidates_drawn
from emogesture.pipeline.timeline import EmotionTimeline, is_timeline
from emogesture.types import EMOTIONS, SMPLXSequence

__all__ = ["AnimationRequest", "AnimationResult", "animate", "emotion_request"]


def emotion_request(text: str | None) -> tuple[str, str | None]:
    """An emotion request -> ``(mode, label)``: ``auto`` (also for None or empty) or ``own`` -> the speech's
    own emotion, ``(mode, None)``; an emotion label (any case) -> ``("auto", label)``, an edit toward it."""
    value = (text or "auto").strip().lower()
    if value in ("auto", "own"):
        return value, None
    if value not in EMOTIONS:
        raise EmogestureError(f"--emotion {text!r}: unknown; use auto, own or one of {', '.join(EMOTIONS)}")
    return "auto", value


def parse_span(text: str) -> tuple[float, float]:
    """``"START-END"`` (seconds, e.g. ``"0-15"`` or ``"2.5-14"``) -> ``(start, end)``; a one-line error
    otherwise."""
    start, sep, end = text.strip().partition("-")
    try:
        if not sep:
            raise ValueError
        return float(start), float(end)
    except ValueError:
        raise EmogestureError(f"--neutral-span {text!r}: START-END in seconds, e.g. 0-15") from None


#: added to the speech's summary when its own emotion, read alone, comes from a voice mostly unlike the
#: training voices
NEUTRAL_HINT = "; try --neutral-from"
#: the longest line ``--verbose`` prints
LINE_CHARS = 120
#: the detail behind :data:`NEUTRAL_HINT`
NEUTRAL_DETAIL = ("heard alone, a real person's even voice can sound emotional to this model: a calm recording of the "
                  "same speaker (--neutral-from), or a calm stretch of this one (--neutral-span START-END), reads "
                  "its emotion against their own voice")

@dataclass
class AnimationRequest:
    """What to animate and where to write it; checked when made (:meth:`validate`).

    ``emotion``: ``auto`` (the speech's own emotion, blended toward neutral where the voice is unlike the
    training voices), ``own`` (as heard), a label of :data:`~emogesture.types.EMOTIONS` to animate
    instead, or a timeline of keyframes ``"0:neutral,12:anger,30:sadness@0.5"``
    (:mod:`emogesture.pipeline.timeline`). ``emotion_weight``: 0..1 between the speech's own emotion (0) and the label or the
    ``emotion_from`` recording (1); None means 1, and a weight without either target is an error.
    ``formats``: names of :data:`~emogesture.export.FORMATS` (or one comma-separated string).
    ``samples``: how many different sequences to draw from ``seed`` (files ``_0``, ``_1``, ...);
    ``generation``: the generation settings of this request (None: the model's own,
    :attr:`GesturePipeline.generation`), e.g. ``replace(pipe.generation, seam_candidates=1)``. Paths may be given as strings; they are held as :class:`~pathlib.Path`.
    """

    speech: Path
    out: Path
    emotion: str = "auto"
    emotion_weight: float | None = None
    emotion_from: Path | None = None
    style_from: Path | None = None
    #: a recording of the same speaker speaking without emotion: the speech's emotion is read against it
    #: (:mod:`emogesture.pipeline.neutral_reference`)
    neutral_from: Path | None = None
    #: seconds ``(start, end)`` of the neutral recording to read against, or ``"START-END"``; without
    #: ``neutral_from``, a stretch of the speech itself (a calm opening, say); None: the whole recording
    neutral_span: tuple[float, float] | str | None = None
    formats: tuple[str, ...] = DEFAULT_FORMATS
    seed: int = 0
    samples: int = 1
    generation: GenerationConfig | None = None
    overwrite: bool = False
    #: leave outputs that exist as they are and write only the missing ones (nothing at all when every
    #: output exists): how an interrupted batch resumes; generation is reproducible, so they are the files
    #: an uninterrupted run writes
    skip_existing: bool = False
    #: the bones of the bvh, glb and fbx files: ``smplx`` or ``mixamo`` (:mod:`emogesture.motion.rigs`)
    skeleton: str = "smplx"
    #: a face too (:mod:`emogesture.pipeline.face`): ARKit blendshapes in the npz, the jaw and eyes in the poses
    face: bool = False
    mode: str = field(init=False, default="auto")  # auto / own, from ``emotion``
    label: str | None = field(init=False, default=None)  # the label edited toward, from ``emotion``
    timeline: EmotionTimeline | None = field(init=False, default=None)  # keyframes, from ``emotion``
    weight: float = field(init=False, default=1.0)  # ``emotion_weight`` with None read as 1

    def __post_init__(self) -> None:
        self.speech, self.out = Path(self.speech), Path(self.out)
        self.emotion_from = None if self.emotion_from is None else Path(self.emotion_from)
        self.style_from = None if self.style_from is None else Path(self.style_from)
        self.neutral_from = None if self.neutral_from is None else Path(self.neutral_from)
        if isinstance(self.neutral_span, str):
            self.neutral_span = parse_span(self.neutral_span)
        self.validate()

    def validate(self) -> None:
        """Check the request (without reading any file) and set :attr:`mode`, :attr:`label` and
        :attr:`weight`; raises :class:`EmogestureError` with a one-line message naming the problem."""
        text = self.formats if isinstance(self.formats, str) else ",".join(self.formats)
        self.formats = parse_formats(text)
        if "arkit" in self.formats and not self.face:
            raise EmogestureError("--format arkit writes the face: add --face")
        self.timeline = EmotionTimeline.parse(self.emotion) if is_timeline(self.emotion) else None
        self.mode, self.label = ("auto", None) if self.timeline is not None else emotion_request(self.emotion)
        if self.timeline is not None and (self.emotion_from is not None or self.emotion_weight is not None):
            raise EmogestureError("an --emotion timeline holds its own labels and weights (TIME:LABEL@WEIGHT); "
                                  "it takes no --emotion-from or --emotion-weight")
        if self.label is not None and self.emotion_from is not None:
            raise EmogestureError(f"--emotion {self.label} and --emotion-from {self.emotion_from}: choose one target "
                                  "emotion")
        if self.emotion_weight is not None and self.label is None and self.emotion_from is None:
            raise EmogestureError("--emotion-weight needs --emotion LABEL or --emotion-from WAV (a target to blend "
                                  "toward)")
        self.weight = 1.0 if self.emotion_weight is None else self.emotion_weight
        if not 0.0 <= self.weight <= 1.0:
            raise EmogestureError(f"--emotion-weight {self.weight}: must be between 0 and 1")
        if self.samples < 1:
            raise EmogestureError("--samples must be at least 1")
        if self.out.exists() and not self.out.is_dir():
            raise EmogestureError(f"{self.out}: is a file; --out must be a folder")
        rig_named(self.skeleton)
        if self.neutral_span is not None:
            start, end = (float(t) for t in self.neutral_span)
            if not 0.0 <= start < end:
                raise EmogestureError(f"--neutral-span {start:g}-{end:g}: START-END in seconds, START >= 0 and "
                                      "END after it")
            if end - start < MIN_SECONDS:
                raise EmogestureError(f"--neutral-span {start:g}-{end:g}: {end - start:g} s; a neutral reference "
                                      f"needs at least {MIN_SECONDS:g} s")
            self.neutral_span = (start, end)
        if self.overwrite and self.skip_existing:
            raise EmogestureError("--overwrite and --skip-existing: choose one")

    @property
    def edited(self) -> bool:
        """Whether anything comes from elsewhere: an emotion label or recording, or a style recording."""
        return bool(self.emotion_from or self.label or self.style_from or self.timeline)

    @property
    def neutral_source(self) -> Path | None:
        """The recording the speech's emotion is read against: ``neutral_from``, or the speech itself when only
        a span is given; None: none."""
        return self.neutral_from or (self.speech if self.neutral_span is not None else None)

    def neutral_name(self, short: bool = False) -> str | None:
        """The neutral reference as reports (``short``: videos) name it: the file (its name alone) and the span's
        seconds."""
        source = self.neutral_source
        if source is None:
            return None
        return reference_name(source.name if short else source, self.neutral_span)

    @property
    def tag(self) -> str:
        """The output names' edit part: ``_emotion-<stem>`` / ``_emotion-<label>``, ``_style-<stem>``,
        ``_neutral-<stem>``, ``_own``."""
        tag = ""
        if self.emotion_from:
            tag += f"_emotion-{self.emotion_from.stem}"
        if self.label:
            tag += f"_emotion-{self.label}"
        if self.timeline is not None:
            tag += f"_emotion-{self.timeline.tag}"
        if self.style_from:
            tag += f"_style-{self.style_from.stem}"
        if self.neutral_source is not None:  # after the edits, before _own
            tag += f"_neutral-{self.neutral_source.stem}"
            if self.neutral_span is not None:
                tag += "-{:g}-{:g}s".format(*self.neutral_span)
        return tag + ("_own" if self.mode == "own" else "")

    def outputs(self) -> list[Path]:
        """Every file this request writes: each sample's files in format order, then the perception report."""
        return [p for stem in self.stems() for p in export_paths(stem, self.formats).values()] + [self.perception_path]

    def stems(self) -> list[Path]:
        """``out/<speech><tag>_seed<seed>_<k>`` for each sample ``k`` (no extension)."""
        return [self.out / output_stem(self.speech, self.seed, k, self.tag) for k in range(self.samples)]

    @property
    def perception_path(self) -> Path:
        """``out/<speech><tag>_seed<seed>_perception.json``."""
        return self.out / f"{self.speech.stem}{self.tag}_seed{self.seed}_perception.json"

    def video_label(self, sample: int) -> str | list[tuple[float, str]]:
        """The three lines shown in a video: the speech's name, where emotion and style come from, seed and
        sample; with a timeline, ``(from seconds, lines)`` for each keyframe, naming the emotion in force."""
        style = f"style from {self.style_from.name}" if self.style_from else f"style: own ({self.mode})"
        if self.timeline is not None:
            return [(t, f"{self.speech.name}\nemotion: {name} (from {t:g} s)  |  {style}\nseed {self.seed}, "
                        f"sample {sample}") for t, name in self.timeline.video_labels()]
        emotion = (f"emotion: {self.label}" if self.label else f"emotion from {self.emotion_from.name}"
                   if self.emotion_from else f"emotion: own ({self.mode})")
        if (self.label or self.emotion_from) and self.weight < 1.0:
            emotion += f" x{self.weight:g}"
        if self.neutral_source is not None and (not (self.label or self.emotion_from) or self.weight < 1.0):
            emotion += f" against {self.neutral_name(short=True)}"  # the speech's own emotion is read against it
        return f"{self.speech.name}\n{emotion}  |  {style}\nseed {self.seed}, sample {sample}"


@dataclass
class AnimationResult:
    """What :func:`animate` wrote and made: per sample the files in format order, the perception report
    (the speech first, then the ``emotion_from`` recording if any), its one-line summaries and the details
    behind each (:meth:`PerceivedEmotion.details`), and the
    ``samples`` SMPL-X sequences of ``round(duration * fps)`` frames."""

    files: list[list[Path]]
    perception_path: Path
    perceived: list[PerceivedEmotion]
    summaries: list[str]
    sequences: list[SMPLXSequence]
    details: list[list[str]] = field(default_factory=list)
    #: True when ``skip_existing`` found every output in place (nothing was computed or written)
    skipped: bool = False
    #: the speech as the pipeline heard it (16 kHz mono ``[N]`` float32; None when skipped)
    speech: np.ndarray | None = None


def faces(sequences: list[SMPLXSequence], wave: np.ndarray, request: AnimationRequest,
          perceived: list[PerceivedEmotion]) -> list[SMPLXSequence]:
    """Each sequence with its face: the speech's phones (when pocketsphinx is installed; else the jaw follows
    the voice) and the emotion animated, sample ``k`` drawing its blinks and gaze from ``seed + k``."""
    phones = recognise_phones(wave, TARGET_SAMPLE_RATE) if recogniser_installed() else None
    out = []
    for k, seq in enumerate(sequences):
        emotions = animated_emotions(perceived[0], request.mode, seq.num_frames, label=request.label,
                                     weight=request.weight, timeline=request.timeline, fps=seq.fps,
                                     source=perceived[1] if len(perceived) > 1 else None)
        out.append(with_face(seq, wave, TARGET_SAMPLE_RATE, emotions, phones, seed=request.seed + k))
    return out


def animate(pipe: GesturePipeline, request: AnimationRequest, *, progress: bool = False,
            report: Callable[[str], None] | None = None,
            written: Callable[[Path, SMPLXSequence], None] | None = None, verbose: bool = False) -> AnimationResult:
    """Animate ``request.speech`` with ``pipe`` and write every output of ``request``.

    Reads the speech and the edit recordings, refuses existing outputs (unless ``request.overwrite``; with
    ``request.skip_existing`` they are left as they are, and nothing is computed when all exist)
    before computing anything, encodes the speech, perceives its emotion (and that of the
    ``emotion_from`` recording, whose emotion is blended like the speech's under ``auto``), draws the
    samples, exports each, and writes the perception report as a JSON list, whole or not at all.
    ``progress``: tqdm bars on stderr. ``report(summary)`` is called with each perception summary as
    soon as it is known (``verbose``: followed by its details, one indented line each);
    ``written(path, sequence)`` after each animation file. Prints nothing itself.
    """
    request.validate()
    wave = pipe.load_speech(request.speech)
    emotion_wave = pipe.load_speech(request.emotion_from) if request.emotion_from is not None else None
    style_wave = pipe.load_speech(request.style_from) if request.style_from is not None else None
    neutral_wave = (None if request.neutral_source is None else
                    pipe.load_neutral_reference(request.neutral_source, request.neutral_span))
    if request.timeline is not None:
        request.timeline.check_duration(len(wave) / TARGET_SAMPLE_RATE, request.speech)
    edit = (EditRequest(emotion_weight=request.weight, emotion_label=request.label,
                        emotion_timeline=request.timeline) if request.edited else None)
    stems, perception_path = request.stems(), request.perception_path
    if request.skip_existing:  # a format is written for a sample where its file is missing
        formats = [tuple(f for f, path in export_paths(stem, request.formats).items() if not path.exists())
                   for stem in stems]
        if not any(formats) and perception_path.exists():
            return AnimationResult([[] for _ in stems], perception_path, [], [], [], skipped=True)
    else:
        formats = [request.formats] * len(stems)
        for stem in stems:
            for path in export_paths(stem, request.formats).values():
                check_output(path, request.overwrite)
        check_output(perception_path, request.overwrite)

    settings = pipe.settings(request.generation)
    with tqdm(total=len(window_starts(len(wave) / TARGET_SAMPLE_RATE, WINDOW_SECONDS, settings.hop_seconds)),
              desc="encoding speech", unit="window", disable=not progress, leave=False) as bar:
        encoded = pipe.encode(wave, progress=bar.update, generation=settings)
    reference = (None if neutral_wave is None else
                 pipe.neutral_reference(neutral_wave, request.neutral_name(), generation=settings))
    heard, encoded = pipe.perceive_against(encoded, str(request.speech), reference)
    perceived = [heard]
    if request.timeline is not None:  # the emotion in force in each window, in the report
        perceived[0].in_force = request.timeline.window_report(
            request.timeline.shares(encoded[1], WINDOW_SECONDS, len(wave) / TARGET_SAMPLE_RATE))
    if edit is not None and emotion_wave is not None:
        enc, starts = pipe.encode(emotion_wave, parts=pipe.edit_source_parts("emotion"), generation=settings)
        perceived.append(pipe.perceive(enc, starts, source=str(request.emotion_from)))
        edit.emotion_from = (auto_emotion(enc.emotion, enc.style, perception_of(pipe.speech),
                                          heard_by_front_end(enc, perception_of(pipe.speech)))
                             if request.mode == "auto" else enc.emotion)
    if edit is not None and style_wave is not None:
        edit.style_from = pipe.encode(style_wave, parts=pipe.edit_source_parts("style"), generation=settings)[0].style
    summaries = [p.summary(request.mode) for p in perceived]
    details = [p.details(request.mode) for p in perceived]
    own = request.label is None and request.emotion_from is None and request.timeline is None
    if reference is None and own and perceived[0].unlike_training_voices:  # its own emotion, read alone
        summaries[0] += NEUTRAL_HINT
        details[0].append(NEUTRAL_DETAIL)
    for line, more in zip(summaries, details):
        if report is not None:
            report("\n".join([line] + [textwrap.fill(d, LINE_CHARS, initial_indent="  ", subsequent_indent="    ",
                                                                  break_long_words=False, break_on_hyphens=False)
                                        for d in more]) if verbose else line)

    windows = len(encoded[1])
    with tqdm(total=windows * candidates_drawn(windows, settings.seam_candidates) * request.samples,
              desc="drawing windows", unit="window", disable=not progress, leave=False) as bar:
        sequences = pipe.generate(wave, edit=edit, seed=request.seed, samples=request.samples,
                                  emotion_mode=request.mode, encoded=encoded, progress=bar.update,
                                  generation=settings)
    if request.face:
        sequences = faces(sequences, wave, request, perceived)
    files = []
    for k, (seq, stem) in enumerate(zip(sequences, stems)):
        done = None if written is None else (lambda path, seq=seq: written(path, seq))
        files.append(export_sequence(seq, stem, formats[k], audio=(wave, TARGET_SAMPLE_RATE),
                                     label=request.video_label(k), overwrite=request.overwrite, progress=progress,
                                     written=done, skeleton=request.skeleton) if formats[k] else [])
    if not (request.skip_existing and perception_path.exists()):
        with atomic_output(perception_path, request.overwrite) as tmp:
            tmp.write_text("[\n" + ",\n".join(p.to_json().rstrip() for p in perceived) + "\n]\n")
    return AnimationResult(files, perception_path, perceived, summaries, sequences, details, speech=wave)
