"""``emogesture generate`` (speech -> animation files) and ``emogesture export`` (npz -> bvh / glb / fbx / mp4)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

EMOTION_HELP = ("auto (default: the speech's own emotion, blended toward neutral where the voice is unlike the "
                "training voices), own (the speech's own emotion as heard), or a label to animate instead: "
                "neutral, happiness, anger, sadness, contempt, surprise, fear, disgust; or a timeline of keyframes "
                "TIME:LABEL[@WEIGHT], e.g. \"0:neutral,12:anger,30:sadness@0.5\" (seconds; each holds until the next)")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("generate", help="animate speech recordings (npz, bvh, mp4, glb, fbx; a face with --face)",
                       description="Animate each SPEECH with the bundled model (or --model), loaded once. Emotion and "
                       "speaker style can come from other recordings, or the emotion from a label. Writes "
                       "<speech>[_edit]_seed<seed>_<sample>.{npz,bvh,mp4,glb,fbx} and <speech>[_edit]_seed<seed>_perception.json "
                       "into --out; existing files are never replaced without --overwrite. A recording that fails "
                       "prints its error and the others go on (exit status 2 if any failed).")
    p.add_argument("speech", type=Path, nargs="+",
                   help="speech audio files (wav, flac, ogg, mp3, ...; any rate) and folders of them")
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
    p.add_argument("--neutral-from", type=Path, metavar="WAV",
                   help="a recording of the same speaker speaking without emotion (10 s or more): the speech's "
                        "emotion is heard and animated relative to this speaker's neutral voice")
    p.add_argument("--neutral-span", metavar="START-END",
                   help="seconds of the --neutral-from recording to use (e.g. 0-15); without --neutral-from, a calm "
                        "stretch of each speech itself, such as its opening")
    p.add_argument("--format", default="npz,bvh,mp4",
                   help="comma-separated output formats: npz, bvh, mp4, glb, fbx, arkit (fbx needs Blender; arkit, "
                        "a Live Link Face CSV, needs --face; default npz,bvh,mp4)")
    p.add_argument("--skeleton", default="smplx", choices=["smplx", "mixamo"],
                   help="bones of the bvh, glb and fbx files: smplx (55, SMPL-X names; default) or mixamo (52, "
                        "Mixamo's names, for game engines' humanoid rigs)")
    p.add_argument("--face", action="store_true",
                   help="animate the face too: lips from the speech's phones, the emotion's expression, blinks and "
                        "gaze, as ARKit blendshapes in the npz ('arkit', 'arkit_names') and the SMPL-X jaw and eyes")
    p.add_argument("--seed", type=int, default=0, help="seed of the first sample (default 0)")
    p.add_argument("--samples", type=int, default=1, help="number of different samples (default 1)")
    p.add_argument("--seam-candidates", type=int, default=None,
                   help="samples drawn per window, one kept per window so the worst seam moves least (default: the "
                        "model's setting, 4 for the bundled model; 1 = off)")
    p.add_argument("--device", default="auto", help="auto (a CUDA GPU when visible, else cpu), cpu, cuda or cuda:N")
    p.add_argument("--precision", default="auto", choices=["auto", "fp32", "bf16"],
                   help="auto (default): bf16 autocast where bf16 is native (GPU, CPU with avx512_bf16/AMX), "
                        "else fp32; fp32: the exact path")
    p.add_argument("--no-acceleration", action="store_true",
                   help="plain torch only: no oneDNN private ops or blocked attention (also EMOGESTURE_ACCELERATION=0)")
    p.add_argument("--overwrite", action="store_true", help="replace existing output files")
    p.add_argument("--skip-existing", action="store_true",
                   help="leave existing outputs as they are and write only the missing ones (resumes a batch)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--verbose", action="store_true",
                   help="after each recording's one-line summary, how it was heard and why windows were blended")
    p.set_defaults(func=run_generate)

    p = sub.add_parser("export", help="turn a BEAT2/SMPL-X .npz (generated or your own mocap) into bvh/glb/fbx/mp4",
                       description="Write FILE.npz as FILE.bvh, FILE.glb, FILE.fbx and/or FILE.mp4 (into --out, "
                       "default beside it).")
    p.add_argument("npz", type=Path, help="an SMPL-X animation in BEAT2's .npz format")
    p.add_argument("--format", default="bvh,mp4",
                   help="comma-separated: npz, bvh, glb, fbx, mp4, arkit (an npz with a face; default bvh,mp4)")
    p.add_argument("--audio", type=Path, metavar="WAV", help="speech to put into the video")
    p.add_argument("--skeleton", default="smplx", choices=["smplx", "mixamo"],
                   help="bones of the bvh, glb and fbx files: smplx (default) or mixamo")
    p.add_argument("-o", "--out", type=Path, help="output folder (default: beside the npz)")
    p.add_argument("--overwrite", action="store_true", help="replace existing output files")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run_export)


def run_generate(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from emogesture.errors import EmogestureError
    from emogesture.pipeline.animate import AnimationRequest
    from emogesture.pipeline.batch import animate_files, batch_summary, speech_files
    from emogesture.pipeline.generate import GesturePipeline
    from emogesture.runtime import resolve_device, set_acceleration

    if args.seam_candidates is not None and args.seam_candidates < 1:
        raise EmogestureError("--seam-candidates must be at least 1")
    template = AnimationRequest(args.speech[0], args.out, emotion=args.emotion or "auto",
                                emotion_weight=args.emotion_weight, emotion_from=args.emotion_from,
                                style_from=args.style_from, neutral_from=args.neutral_from,
                                neutral_span=args.neutral_span, formats=args.format,
                                seed=args.seed, samples=args.samples,
                                overwrite=args.overwrite,
                                skip_existing=args.skip_existing, skeleton=args.skeleton, face=args.face)
    speeches = speech_files(args.speech)
    if args.no_acceleration:
        set_acceleration(False)
    device = resolve_device(args.device)
    pipe = GesturePipeline.from_run(args.model, args.speech_model, device=device, precision=args.precision)
    if args.seam_candidates is not None:
        template.generation = replace(pipe.generation, seam_candidates=args.seam_candidates)
    items = animate_files(pipe, speeches, template, progress=not args.quiet and sys.stderr.isatty(), report=print,
                          written=lambda path, seq: print(f"{path}  ({seq.num_frames} frames, {seq.duration:.2f} s)"),
                          finished=_finished, verbose=args.verbose)
    if len(items) > 1:
        print(batch_summary(items))
    return 2 if any(item.error for item in items) else 0


def _finished(item) -> None:
    if item.error is not None:
        print(f"emogesture generate: error: {item.error}", file=sys.stderr)
    elif item.skipped:
        print(f"{item.speech}: every output already exists (skipped)")
    else:
        print(item.result.perception_path)


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
                    written=lambda path: print(f"{path}  ({seq.num_frames} frames, {seq.duration:.2f} s)"),
                    skeleton=args.skeleton)
    return 0
