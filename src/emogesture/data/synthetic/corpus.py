"""``build_corpus``: the synthetic BEAT2-layout corpus (docs/design.md, 'Data' and 'Synthetic corpus').

Layout under the output folder: ``smplxflame_30/<take>.npz``, ``wave16k/<take>.wav`` (16 kHz int16
mono), ``textgrid/<take>.TextGrid`` (a ``words`` tier, approximate timings), ``sem/<take>.txt``
(one row per gesture stroke), ``train_test_split.csv`` and ``corpus.json`` (config, generating
factors, engine versions, takes). ``corpus.json`` is written last: its presence marks a complete
corpus. A hidden ``.emogesture-corpus.json`` records the config from the first moment, so a
resumed build refuses to mix two corpora.

Splits hold out whole texts: per emotion the last text is test, the one before it val when there
are at least 4 texts per emotion, the rest train; every speaker speaks every text.
"""

from __future__ import annotations

import json
import multiprocessing
import shutil
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from os import PathLike
from pathlib import Path

from tqdm import tqdm

from emogesture.data.beat import EMOTION_TAKE_RANGES, EMOTIONS, write_split_csv
from emogesture.data.synthetic.factors import EMOTION_FACTORS, ENGINES, make_speaker
from emogesture.data.synthetic.speech import check_engines, engine_versions
from emogesture.data.synthetic.takes import (
    SUBDIRS,
    TakePlan,
    _replace_atomic,
    base_sentences,
    build_take,
    check_take,
)
from emogesture.data.synthetic.text import make_text
from emogesture.errors import ConfigError, EmogestureError

#: 2: the hanging arm turns inwards at most MAX_ADDUCTION; 3: the lively generator; 4: one voice per BEAT
#: speaker id (30 voices; two voice families only among the held-out actors; speakers 1-14 as before);
#: 5: hands that curl and take shapes, a body that turns toward listeners, forearms toward the midline and
#: hands together, fewer strokes with jittered apexes, holds and rests; 6: arms that hang nearer the body,
#: a wider turn toward the listeners, stroke apexes a little further off their onsets; 9: livelier strokes
#: (more, larger, the forearm carrying the beat) whose apexes keep nearer their onsets, each slowed only as
#: much as keeps its hand below MAX_HAND_SPEED, so the emotions keep their differences in speed; 10: version 9
#: with the upper arm's share of a stroke a little smaller (its shoulder turns within the real range); 11: hands
#: that travel between places in the gesture space between strokes (elbow, shoulder and collar; not locked to the
#: syllables), stroke apexes that never land on one another, a forearm's inward turn that follows the elbow's
#: bend as the elbow makes it
CORPUS_VERSION = 11
MARKER = ".emogesture-corpus.json"
MANIFEST = "corpus.json"
SPLIT_FILE = "train_test_split.csv"


#: Settings added after corpora had been built at 1: a marker without one was built at 1.
SCALES_ADDED_LATER = ("emotion_prosody_scale",)
#: Settings tried and not adopted, removed (experiments/reports/): a marker that holds one was built with it
#: at another value than this version's fixed 1, so it is a corpus of other settings.
SCALES_RETIRED = ("speaker_prosody_scale",)


@dataclass
class CorpusConfig:
    """What to generate. ``workers`` only changes speed, never the bytes written."""

    speakers: int = 8  # 1-30, BEAT speaker ids 1..speakers
    texts_per_emotion: int = 4  # 1-6 (the smallest emotion range has 6 take ids)
    min_take_seconds: float = 20.0
    seed: int = 0
    workers: int = 2
    engines: tuple[str, ...] = ENGINES
    #: Strength of the emotions' speech prosody (1 = the factor table; see ``scale_prosody``). The
    #: default 1.5 makes the emotion audible on held-out texts (at 1, hand-made prosody features
    #: classify it at 0.82-0.85; experiments/README.md); corpora built before it were at 1.
    emotion_prosody_scale: float = 1.5

    def validate(self) -> None:
        """Raise ConfigError on an impossible setting."""
        if not 1 <= self.speakers <= 30:
            raise ConfigError(f"speakers must be 1-30, got {self.speakers}")
        smallest = min(hi - lo + 1 for lo, hi in EMOTION_TAKE_RANGES)
        if not 1 <= self.texts_per_emotion <= smallest:
            raise ConfigError(f"texts_per_emotion must be 1-{smallest}, got {self.texts_per_emotion}")
        if not 1.0 <= self.min_take_seconds <= 600.0:
            raise ConfigError(f"min_take_seconds must be 1-600, got {self.min_take_seconds}")
        if self.workers < 1:
            raise ConfigError(f"workers must be >= 1, got {self.workers}")
        if not 0.0 <= self.emotion_prosody_scale <= 3.0:
            raise ConfigError(f"emotion_prosody_scale must be 0-3, got {self.emotion_prosody_scale}")
        if not self.engines or set(self.engines) - set(ENGINES):
            raise ConfigError(f"engines must be a non-empty subset of {ENGINES}, got {self.engines}")

    def identity(self) -> dict:
        """The fields that decide the output bytes (everything but ``workers``)."""
        d = asdict(self)
        d.pop("workers")
        d["engines"] = list(self.engines)
        for key in SCALES_ADDED_LATER:  # corpora built at 1 before the setting existed keep their identity
            if d[key] == 1.0:
                d.pop(key)
        return d


def corpus_emotion_prosody_scale(root: Path) -> float:
    """The emotion prosody scale a built corpus at ``root`` was made with (1 for corpora from before it)."""
    manifest = json.loads((Path(root) / MANIFEST).read_text(encoding="utf-8"))
    return float(manifest["config"].get("emotion_prosody_scale", 1.0))


@dataclass
class CorpusSummary:
    """What a build did: take counts, audio hours, takes per split, wall time."""

    out_dir: str
    takes: int
    built: int
    skipped: int
    total_seconds: float
    splits: dict[str, int] = field(default_factory=dict)
    speakers: int = 0
    texts: int = 0
    elapsed: float = 0.0

    def format(self) -> str:
        """A few human-readable lines."""
        split = ", ".join(f"{k} {v}" for k, v in sorted(self.splits.items()))
        return (f"corpus {self.out_dir}: {self.takes} takes ({self.speakers} speakers x {self.texts} texts), "
                f"{self.total_seconds / 60:.1f} min of speech\n"
                f"  built {self.built}, already complete {self.skipped}; splits: {split}\n"
                f"  elapsed {self.elapsed:.1f} s")


def _differences(found, wanted: dict) -> str:
    """``key: <found> there, <wanted> here`` for each setting a found corpus marker differs in."""
    if not isinstance(found, dict) or not isinstance(found.get("config"), dict):
        return "unreadable marker"
    there = dict(found["config"], version=found.get("version"))
    here = dict(wanted["config"], version=wanted["version"])
    for key in SCALES_ADDED_LATER + SCALES_RETIRED:  # older markers omit the setting at 1
        there.setdefault(key, 1.0)
        here.setdefault(key, 1.0)
    keys = sorted(k for k in set(there) | set(here) if there.get(k) != here.get(k))
    return ", ".join(f"{k}: {there.get(k)} there, {here.get(k)} here" for k in keys) or "same settings, other format"


def plan_takes(config: CorpusConfig) -> tuple[list[TakePlan], dict[str, str]]:
    """All takes (speaker-major) and ``{take: split}``."""
    plans, splits = [], {}
    n = config.texts_per_emotion
    for spk in range(1, config.speakers + 1):
        for emo, (lo, _) in enumerate(EMOTION_TAKE_RANGES):
            for i in range(n):
                plan = TakePlan(spk, lo + i, emo, i, config.seed, float(config.min_take_seconds),
                                tuple(config.engines), float(config.emotion_prosody_scale))
                plans.append(plan)
                splits[plan.name] = text_split(i, n)
    return plans, splits


def text_split(text_index: int, texts_per_emotion: int) -> str:
    """Split of a text: last = test, the one before = val (if >= 4 texts), else train."""
    if texts_per_emotion >= 2 and text_index == texts_per_emotion - 1:
        return "test"
    if texts_per_emotion >= 4 and text_index == texts_per_emotion - 2:
        return "val"
    return "train"


def _manifest(config: CorpusConfig, plans: list[TakePlan], splits: dict[str, str],
              durations: dict[str, float], versions: dict[str, str]) -> str:
    texts = []
    for p in plans:
        if p.speaker_id == 1:
            texts.append({"take": p.take, "emotion": EMOTIONS[p.emotion], "split": splits[p.name],
                          "text": make_text(p.seed, EMOTIONS[p.emotion], p.text_index, base_sentences(p))})
    doc = {
        "format": "emogesture synthetic BEAT2-layout corpus",
        "version": CORPUS_VERSION,
        "config": config.identity(),
        "engine_versions": versions,
        "word_timing": "approximate: voiced time shared out by syllable count",
        "emotions": {k: asdict(v) for k, v in EMOTION_FACTORS.items()},
        "speakers": {str(s): make_speaker(config.seed, s, config.engines).to_json()
                     for s in range(1, config.speakers + 1)},
        "texts": texts,
        "takes": {name: {"split": splits[name], "seconds": round(durations[name], 5)} for name in sorted(durations)},
    }
    return json.dumps(doc, indent=1, sort_keys=True) + "\n"


def _init_worker() -> None:
    import torch

    torch.set_num_threads(1)


def _clear(out: Path) -> None:
    for sub in SUBDIRS.values():
        shutil.rmtree(out / sub, ignore_errors=True)
    for name in (MANIFEST, SPLIT_FILE, MARKER):
        (out / name).unlink(missing_ok=True)


def build_corpus(out_dir: str | PathLike[str], config: CorpusConfig, *, progress: bool = True,
                 overwrite: bool = False, resume: bool = True) -> CorpusSummary:
    """Generate (or finish) the synthetic corpus in ``out_dir``; returns a summary.

    Complete takes are kept, missing or damaged ones (re)built; a complete corpus is left untouched.
    ``overwrite`` deletes a synthetic corpus found there first (only one this generator wrote, with
    its marker file). With ``resume=False`` a folder that already holds a corpus is an error. A folder
    holding a corpus of another config is always an error (unless ``overwrite``), as is a non-empty
    folder that is not a synthetic corpus, with or without ``overwrite``.
    """
    start = time.perf_counter()
    config.validate()
    check_engines(tuple(config.engines))
    out = Path(out_dir)
    identity = {"version": CORPUS_VERSION, "config": config.identity()}
    marker = out / MARKER
    if overwrite and marker.is_file():
        _clear(out)  # this generator's files only; anything else in the folder stays
    elif out.is_dir() and any(out.iterdir()):
        if not marker.is_file():
            raise EmogestureError(f"{out}: not empty and not a synthetic corpus; choose a new folder")
        try:
            found = json.loads(marker.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            found = None
        if found != identity:
            raise EmogestureError(f"{out}: holds a corpus with other settings ({_differences(found, identity)}); "
                                  "choose a new folder or rebuild it with --overwrite")
        if not resume:
            raise EmogestureError(f"{out}: already holds a corpus; resume it (--resume) or choose a new folder")
    out.mkdir(parents=True, exist_ok=True)
    if not marker.is_file():
        _replace_atomic(marker, lambda p: p.write_text(json.dumps(identity, sort_keys=True) + "\n"))
    for sub in SUBDIRS.values():  # leftovers of an interrupted write
        for tmp in (out / sub).glob(".*.tmp") if (out / sub).is_dir() else ():
            tmp.unlink(missing_ok=True)

    plans, splits = plan_takes(config)
    durations = {p.name: check_take(out, p.name) for p in plans}
    todo = [p for p in plans if durations[p.name] is None]
    if todo or not (out / MANIFEST).is_file() or not (out / SPLIT_FILE).is_file():
        (out / MANIFEST).unlink(missing_ok=True)
        _run(out, todo, config.workers, progress)
        durations = {p.name: check_take(out, p.name) for p in plans}
        broken = [name for name, d in durations.items() if d is None]
        if broken:
            raise EmogestureError(f"{out}: takes failed to build: {', '.join(broken[:5])}")
        _replace_atomic(out / SPLIT_FILE, lambda p: write_split_csv(p, splits))
        text = _manifest(config, plans, splits, durations, engine_versions(tuple(config.engines)))
        _replace_atomic(out / MANIFEST, lambda p: p.write_text(text, encoding="utf-8"))
    counts: dict[str, int] = {}
    for s in splits.values():
        counts[s] = counts.get(s, 0) + 1
    return CorpusSummary(str(out), len(plans), len(todo), len(plans) - len(todo),
                         float(sum(durations.values())), counts, config.speakers,
                         len(EMOTIONS) * config.texts_per_emotion, time.perf_counter() - start)


def _run(out: Path, todo: list[TakePlan], workers: int, progress: bool) -> None:
    bar = tqdm(total=len(todo), unit="take", desc="corpus", disable=not progress or not todo,
               mininterval=0.1 if sys.stderr.isatty() else 15.0)
    try:
        if workers == 1 or len(todo) <= 1:
            for plan in todo:
                build_take(out, plan)
                bar.update()
            return
        ctx = multiprocessing.get_context("spawn")  # no fork after torch threads have started
        with ProcessPoolExecutor(min(workers, len(todo)), mp_context=ctx, initializer=_init_worker) as pool:
            futures = [pool.submit(build_take, out, plan) for plan in todo]
            try:
                for fut in as_completed(futures):
                    fut.result()
                    bar.update()
            except BaseException:
                pool.shutdown(wait=False, cancel_futures=True)
                raise
    finally:
        bar.close()
