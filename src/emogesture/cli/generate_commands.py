"""``emogesture generate`` (speech -> animation files) and ``emogesture export`` (npz -> bvh / mp4)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

EMOTION_HELP = ("auto (default: the speech's own emotion, blended toward neutral where the voice is unlike the "
                "training voices), own (the speech's own emotion as heard), or a label to animate instead: "
                "neutral, happiness, anger, sadness, contempt, surprise, fear, disgust")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("generate", help="animate a speech recording (npz, bvh, mp4)",
                       description="Animate SPEECH with the bundled model (or --model). Emotion and speaker style "
                       "can come from other recordings, or the emotion from a label. Writes "
                       "<speech>[_edit]_seed<seed>_<sample>.{npz,bvh,mp4} and <speech>[_edit]_seed<seed>_perception.json "
                       "into --out; existing files are never replaced without --overwrite.")
    p.add_argument("speech", type=Path, help="speech audio (wav, flac, ogg, mp3; any rate)")
    p.add_argument("-o", "--out", required=True, type=Path, help="output folder")
    p.add_argument("--model", type=Path, help="run folder of `emogesture train gesture` (default: the bundled model)")
    p.add_argument("--speech-model", type=Path, help="speech model run (default: the one the model names)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--emotion-from", type=Path, metavar="WAV", help="take the emotion from this recording")
    g.add_argument("--emotion", metavar="MODE_OR_LABEL", default=None, help=EMOTION_HELP)
    p.add_argument("--emotion-weight", type=float, default=None,
                   help="0..1 blend between the speech's own emotion (0) and the --emotion label or --emotion-from "
                   "recording (1; the default)")
    p.add_argument("--style-from", type=Path, metavar="WAV", help="take the speaker style from this recording")
    p.add_argument("--format", default="npz,bvh,mp4", help="comma-separated output formats (default npz,bvh,mp4)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first sample (default 0)")
    p.add_argument("--samples", type=int, default=1, help="number of different samples (default 1)")
    p.add_argument("--seam-candidates", type=int, default=4,
                   help="samples drawn per window, one kept per window so the worst seam moves least (default 4; 1 = off)")
    p.add_argument("--device", default="auto", help="auto (a CUDA GPU when visible, else cpu), cpu, cuda or cuda:N")
    p.add_argument("--precision", default="auto", choices=["auto", "fp32", "bf16"],
                   help="auto (default): bf16 autocast where bf16 is native (GPU, CPU with avx512_bf16/AMX), "
                        "else fp32; fp32: the exact path")
    p.add_argument("--overwrite", action="store_true", help="replace existing output files")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=run_generate)

    p = sub.add_parser("export", help="turn a BEAT2/SMPL-X .npz (generated or your own mocap) into bvh / mp4",
                       description="Write FILE.npz as FILE.bvh and/or FILE.mp4 (into --out, default beside it).")
    p.add_argument("npz", type=Path, help="an SMPL-X animation in BEAT2's .npz format")
    p.add_argument("--format", default="bvh,mp4", help="comma-separated: npz, bvh, mp4 (default bvh,mp4)")
    p.add_argument("--audio", type=Path, metavar="WAV", help="speech to put into the video")
    p.add_argument("-o", "--out", type=Path, help="output folder (default: beside the npz)")
    p.add_argument("--overwrite", action="store_true", help="replace existing output files")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run_export)


def _emotion_request(args: argparse.Namespace) -> tuple[str, str | None]:
    """``--emotion`` -> (mode, label): mode auto/own for the speech's own emotion, label for an edit."""
    from emogesture.data.beat import EMOTIONS
    from emogesture.errors import EmogestureError

    value = (args.emotion or "auto").strip().lower()
    if value in ("auto", "own"):
        return value, None
    if value not in EMOTIONS:
        raise EmogestureError(f"--emotion {args.emotion!r}: unknown; use auto, own or one of {', '.join(EMOTIONS)}")
    return "auto", value


def run_generate(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from emogesture.audio import TARGET_SAMPLE_RATE, window_starts
    from emogesture.errors import EmogestureError
    from emogesture.export import export_paths, export_sequence, parse_formats
    from emogesture.fileio import atomic_output, check_output
    from emogesture.pipeline.generate import (HOP_SECONDS, WINDOW_SECONDS, EditRequest, GesturePipeline,
                                              candidates_drawn, output_stem)
    from emogesture.pipeline.perception import auto_emotion, perception_of
    from emogesture.runtime import resolve_device

    formats = parse_formats(args.format)
    mode, label = _emotion_request(args)
    if args.emotion_weight is not None and label is None and args.emotion_from is None:
        raise EmogestureError("--emotion-weight needs --emotion LABEL or --emotion-from WAV (a target to blend toward)")
    weight = 1.0 if args.emotion_weight is None else args.emotion_weight
    if not 0.0 <= weight <= 1.0:
        raise EmogestureError(f"--emotion-weight {weight}: must be between 0 and 1")
    if args.samples < 1:
        raise EmogestureError("--samples must be at least 1")
    if args.seam_candidates < 1:
        raise EmogestureError("--seam-candidates must be at least 1")
    if args.out.exists() and not args.out.is_dir():
        raise EmogestureError(f"{args.out}: is a file; --out must be a folder")
    show = not args.quiet and sys.stderr.isatty()

    device = resolve_device(args.device)
    pipe = GesturePipeline.from_run(args.model, args.speech_model, device=device, precision=args.precision)
    wave = pipe.load_speech(args.speech)
    edit, tag = None, ""
    edit_audio = {}
    if args.emotion_from is not None:
        edit_audio["emotion"] = pipe.load_speech(args.emotion_from)
    if args.style_from is not None:
        edit_audio["style"] = pipe.load_speech(args.style_from)
    if args.emotion_from or label or args.style_from:
        edit = EditRequest(emotion_weight=weight, emotion_label=label)
        if args.emotion_from:
            tag += f"_emotion-{args.emotion_from.stem}"
        if label:
            tag += f"_emotion-{label}"
        if args.style_from:
            tag += f"_style-{args.style_from.stem}"
    if mode == "own":
        tag += "_own"
    base = f"{args.speech.stem}{tag}_seed{args.seed}"
    stems = [args.out / output_stem(args.speech, args.seed, k, tag) for k in range(args.samples)]
    perception_path = args.out / f"{base}_perception.json"
    for stem in stems:
        for path in export_paths(stem, formats).values():
            check_output(path, args.overwrite)
    check_output(perception_path, args.overwrite)

    with tqdm(total=len(window_starts(len(wave) / TARGET_SAMPLE_RATE, WINDOW_SECONDS, HOP_SECONDS)),
              desc="encoding speech", unit="window", disable=not show, leave=False) as bar:
        encoded = pipe.encode(wave, progress=bar.update)
    perceived = [pipe.perceive(*encoded, source=str(args.speech))]
    if edit is not None and "emotion" in edit_audio:
        enc, starts = pipe.encode(edit_audio["emotion"], parts=pipe.edit_source_parts("emotion"))
        perceived.append(pipe.perceive(enc, starts, source=str(args.emotion_from)))
        edit.emotion_from = auto_emotion(enc.emotion, enc.style, perception_of(pipe.speech)) if mode == "auto" else enc.emotion
    if edit is not None and "style" in edit_audio:
        edit.style_from = pipe.encode(edit_audio["style"], parts=pipe.edit_source_parts("style"))[0].style
    for p in perceived:
        print(p.summary(mode))

    windows = len(encoded[1])
    with tqdm(total=windows * candidates_drawn(windows, args.seam_candidates) * args.samples, desc="drawing windows",
              unit="window",
              disable=not show, leave=False) as bar:
        sequences = pipe.generate(wave, edit=edit, seed=args.seed, samples=args.samples,
                                  seam_candidates=args.seam_candidates, emotion_mode=mode, encoded=encoded,
                                  progress=bar.update)
    emotion = (f"emotion: {label}" if label else f"emotion from {args.emotion_from.name}" if args.emotion_from
               else f"emotion: own ({mode})")
    if edit is not None and (label or args.emotion_from) and weight < 1.0:
        emotion += f" x{weight:g}"
    style = f"style from {args.style_from.name}" if args.style_from else "style: own"
    for k, (seq, stem) in enumerate(zip(sequences, stems)):
        text = f"{args.speech.name}\n{emotion}  |  {style}\nseed {args.seed}, sample {k}"
        export_sequence(seq, stem, formats, audio=(wave, TARGET_SAMPLE_RATE), label=text, overwrite=args.overwrite,
                        progress=show, written=lambda path: print(f"{path}  ({seq.num_frames} frames, "
                                                                   f"{seq.duration:.2f} s)"))
    with atomic_output(perception_path, args.overwrite) as tmp:
        tmp.write_text("[\n" + ",\n".join(p.to_json().rstrip() for p in perceived) + "\n]\n")
    print(perception_path)
    return 0


def run_export(args: argparse.Namespace) -> int:
    from emogesture.audio import load_audio
    from emogesture.export import export_sequence, parse_formats
    from emogesture.motion import load_smplx_npz

    formats = parse_formats(args.format)
    seq = load_smplx_npz(args.npz)
    audio = load_audio(args.audio) if args.audio is not None else None
    out = args.out if args.out is not None else args.npz.parent
    label = args.npz.name + (f"\naudio: {args.audio.name}" if args.audio else "")
    export_sequence(seq, out / args.npz.stem, formats, audio=audio, label=label, overwrite=args.overwrite,
                    progress=not args.quiet and sys.stderr.isatty(),
                    written=lambda path: print(f"{path}  ({seq.num_frames} frames, {seq.duration:.2f} s)"))
    return 0
