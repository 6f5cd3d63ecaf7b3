"""``emogesture corpus``, ``emogesture prepare`` and ``emogesture labelled-speech``."""

from __future__ import annotations

import argparse
from pathlib import Path

from emogesture.config import load_config


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "corpus",
        help="generate the synthetic BEAT2-layout corpus (speech synthesis + procedural gestures)",
        description="Write a synthetic corpus in the BEAT2 layout. Same seed, same bytes. "
        "Re-running resumes an interrupted build; a complete corpus is left as it is.",
    )
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--speakers", type=int, default=8, help="number of speakers (1-30, default 8)")
    p.add_argument("--texts-per-emotion", type=int, default=4, help="texts per emotion (default 4)")
    p.add_argument("--min-seconds", type=float, default=20.0, help="minimum take length in seconds (default 20)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--workers", type=int, default=2, help="parallel processes (default 2)")
    p.add_argument("--emotion-prosody-scale", type=float, default=1.5,
                   help="strength of the emotions' speech prosody (default 1.5; 1 = the factor table, as in "
                   "corpora built before this default; 0 = every emotion sounds neutral)")
    p.add_argument("--resume", action="store_true",
                   help="continue or re-check an existing corpus in --out instead of refusing")
    p.add_argument("--overwrite", action="store_true",
                   help="delete the synthetic corpus already in --out (e.g. one of other settings) and build anew")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run_corpus)

    p = sub.add_parser(
        "prepare",
        help="cut a BEAT2-layout root into a memory-mappable windows cache",
        description="Idempotent and resumable: re-running does nothing on a complete cache and "
        "continues an interrupted one.",
    )
    p.add_argument("root", type=Path, help="BEAT2 root (smplxflame_30/, wave16k/, sem/, train_test_split.csv)")
    p.add_argument("--out", required=True, type=Path, help="cache folder")
    p.add_argument("--config", type=Path, help="YAML file of preparation settings")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a setting, e.g. --set hop_seconds=2.5 (repeatable)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run_prepare)

    p = sub.add_parser(
        "labelled-speech",
        help="a manifest of emotion-labelled real speech you hold (RAVDESS, CREMA-D, your own), split by speaker",
        description="Find the emotion-labelled recordings under ROOT in a known layout (ravdess: "
        "03-01-EE-II-SS-RR-AA.wav; crema-d: AAAA_SSS_EEE_LL.wav; folders: SPEAKER/EMOTION/*.wav) and write "
        "a manifest (CSV: path,emotion,speaker,split) with whole speakers held out for val and test. "
        "Score a model on its held-out speakers with `evaluate real --labelled MANIFEST`.",
    )
    p.add_argument("layout", choices=["ravdess", "crema-d", "folders"], help="how the recordings are named")
    p.add_argument("root", type=Path, help="folder holding the recordings (searched recursively)")
    p.add_argument("--out", required=True, type=Path, help="manifest to write (.csv)")
    p.add_argument("--val-speakers", type=_speakers, default=2, metavar="N|NAME,...",
                   help="speakers held out for val: a number drawn by --seed, or names (e.g. actor02,actor03,actor12; "
                        "default 2)")
    p.add_argument("--test-speakers", type=_speakers, default=2, metavar="N|NAME,...",
                   help="speakers held out for test, the same way (default 2)")
    p.add_argument("--calm", choices=["drop", "neutral"], default="drop",
                   help="ravdess: its calm clips left out (default) or heard as neutral")
    p.add_argument("--seed", type=int, default=0, help="seed of the speakers' split (default 0)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing manifest")
    p.set_defaults(func=run_labelled_speech)


def _speakers(text: str) -> int | list[str]:
    """``--val-speakers``/``--test-speakers``: a count, or comma-separated speaker names."""
    return int(text) if text.strip().isdigit() else [s.strip() for s in text.split(",") if s.strip()]


def run_corpus(args: argparse.Namespace) -> int:
    from emogesture.data.synthetic import CorpusConfig, build_corpus

    config = CorpusConfig(
        speakers=args.speakers,
        texts_per_emotion=args.texts_per_emotion,
        min_take_seconds=args.min_seconds,
        seed=args.seed,
        workers=args.workers,
        emotion_prosody_scale=args.emotion_prosody_scale,
    )
    summary = build_corpus(args.out, config, progress=not args.quiet, resume=args.resume, overwrite=args.overwrite)
    print(summary.format())
    return 0


def run_prepare(args: argparse.Namespace) -> int:
    from emogesture.data.prepare import PrepareConfig, prepare

    config = load_config(PrepareConfig, args.config, args.overrides)
    result = prepare(args.root, args.out, config, progress=not args.quiet)
    print(result.format())
    return 0


def run_labelled_speech(args: argparse.Namespace) -> int:
    from collections import Counter

    from emogesture.data.labelled_speech import SPLITS, assign_speaker_splits, manifest_text, scan_layout
    from emogesture.fileio import atomic_output, check_output

    check_output(args.out, args.overwrite)
    clips = assign_speaker_splits(scan_layout(args.layout, args.root, args.calm), args.val_speakers,
                                  args.test_speakers, args.seed)
    text = manifest_text(clips, args.out.resolve().parent)
    with atomic_output(args.out, args.overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    speakers = {split: len({c.speaker for c in clips if c.split == split}) for split in SPLITS}
    emotions = Counter(c.emotion for c in clips)
    print(f"wrote {args.out}: {len(clips)} recordings of {sum(speakers.values())} speakers (train {speakers['train']}, "
          f"val {speakers['val']}, test {speakers['test']}); "
          + ", ".join(f"{e} {n}" for e, n in sorted(emotions.items())))
    return 0
