"""``emogesture generate``: speech file -> SMPL-X gesture .npz files (BEAT2 format)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("generate", help="animate a speech recording (SMPL-X .npz, BEAT2 format)",
                       description="Generate gestures for SPEECH. Emotion and speaker style can come from other "
                       "recordings, or the emotion from a label. Existing outputs are never replaced without "
                       "--overwrite.")
    p.add_argument("speech", type=Path, help="speech audio (wav, flac, ogg, mp3; any rate)")
    p.add_argument("--model", required=True, type=Path, help="run folder of `emogesture train gesture`")
    p.add_argument("--speech-model", type=Path, help="speech model run (default: the one the model names)")
    p.add_argument("-o", "--out", required=True, type=Path, help="output folder")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--emotion-from", type=Path, metavar="WAV", help="take the emotion from this recording")
    g.add_argument("--emotion", metavar="LABEL",
                   help="take the emotion from a label: neutral, happiness, anger, sadness, contempt, surprise, "
                   "fear, disgust")
    p.add_argument("--emotion-weight", type=float, default=1.0,
                   help="0..1 blend between the speech's own emotion (0) and the target emotion (1)")
    p.add_argument("--style-from", type=Path, metavar="WAV", help="take the speaker style from this recording")
    p.add_argument("--seed", type=int, default=0, help="seed of the first sample (default 0)")
    p.add_argument("--samples", type=int, default=1, help="number of different samples (default 1)")
    p.add_argument("--seam-candidates", type=int, default=4,
                   help="samples drawn per window, one kept per window so the worst seam moves least (default 4; 1 = off)")
    p.add_argument("--overwrite", action="store_true", help="replace existing output files")
    p.set_defaults(func=run_generate)


def run_generate(args: argparse.Namespace) -> int:
    from emogesture.errors import EmogestureError, OutputExistsError
    from emogesture.motion import save_smplx_npz
    from emogesture.pipeline.generate import EditRequest, GesturePipeline, output_name

    if not 0.0 <= args.emotion_weight <= 1.0:
        raise EmogestureError(f"--emotion-weight {args.emotion_weight}: must be between 0 and 1")
    if args.samples < 1:
        raise EmogestureError("--samples must be at least 1")
    if args.seam_candidates < 1:
        raise EmogestureError("--seam-candidates must be at least 1")
    pipe = GesturePipeline.from_run(args.model, args.speech_model)
    wave = pipe.load_speech(args.speech)
    edit, tag = None, ""
    if args.emotion_from or args.emotion or args.style_from:
        edit = EditRequest(emotion_weight=args.emotion_weight, emotion_label=args.emotion)
        if args.emotion_from:
            edit.emotion_from = pipe.encode_file_latents(args.emotion_from).emotion
            tag += f"_emotion-{args.emotion_from.stem}"
        if args.emotion:
            tag += f"_emotion-{args.emotion}"
        if args.style_from:
            edit.style_from = pipe.encode_file_latents(args.style_from).style
            tag += f"_style-{args.style_from.stem}"
    paths = [args.out / output_name(args.speech, args.seed, k, tag) for k in range(args.samples)]
    if not args.overwrite:
        for path in paths:
            if path.exists():
                raise OutputExistsError(path)
    sequences = pipe.generate(wave, edit=edit, seed=args.seed, samples=args.samples,
                              seam_candidates=args.seam_candidates)
    for seq, path in zip(sequences, paths):
        save_smplx_npz(seq, path, overwrite=args.overwrite)
        print(f"{path}  ({seq.num_frames} frames, {seq.duration:.2f} s)")
    return 0
