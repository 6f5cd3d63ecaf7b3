"""``emogesture evaluate ...`` and ``emogesture model-info ...``."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    ev = sub.add_parser("evaluate", help="evaluate a trained model")
    esub = ev.add_subparsers(dest="model", required=True, metavar="MODEL")
    p = esub.add_parser("speech", help="EA/EF1/SA/SF1, reconstruction errors, linear probes, confusion matrices")
    p.add_argument("run", type=Path, help="run folder of `emogesture train speech`")
    p.add_argument("--data", required=True, type=Path, help="windows cache")
    p.add_argument("--split", default="test", help="split to evaluate (default test)")
    p.add_argument("--out", type=Path, help="output folder (default RUN/eval)")
    p.add_argument("--quadruples", type=int, default=128, help="test quadruples for reconstruction errors")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--overwrite", action="store_true", help="replace existing reports")
    p.set_defaults(func=run_evaluate_speech)

    p = esub.add_parser("gesture", help="SRGR, BA, FGD, Div, GA, jerk of motion sources (paper Table 1)")
    p.add_argument("--data", required=True, type=Path, help="windows cache (its split's ground truth and audio)")
    p.add_argument("--extractor", required=True, type=Path, help="run folder of `emogesture train extractor`")
    p.add_argument("--source", action="append", default=[], metavar="NAME=FOLDER",
                   help="a folder of <take>.npz motion files (BEAT2 format) to score; repeatable")
    p.add_argument("--model", action="append", default=[], metavar="NAME=RUN",
                   help="a trained gesture model (run folder) to generate and score; repeatable, the first is "
                   "'ours' and the others its ablations")
    p.add_argument("--edit-model", metavar="NAME", help="model scored on emotion edits (default: the first)")
    p.add_argument("--long-audio", type=float, default=None, metavar="SECONDS",
                   help="with --model: length of the long-audio seam check (default 65; 0 skips it)")
    p.add_argument("--split", default="test", help="split to evaluate (default test)")
    p.add_argument("--out", required=True, type=Path, help="output folder for JSON, markdown and PNGs")
    p.add_argument("--no-baselines", action="store_true", help="skip mean pose / mismatched / shifted baselines")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--overwrite", action="store_true", help="replace existing reports")
    p.set_defaults(func=run_evaluate_gesture)

    p = esub.add_parser("real", help="real recorded speech: perception, trust and motion beside held-out corpus voices",
                        description="Generate for real read speech (Debian's pocketsphinx-testdata and "
                        "asterisk-core-sounds-en-g722) and for the "
                        "held-out split's takes of the same emotion; report the emotion heard per window, the "
                        "windows --emotion auto trusts, and where the hands work, with pass/fail checks.")
    p.add_argument("--model", type=Path, help="gesture model run folder or JSON (default: the bundled model)")
    p.add_argument("--data", required=True, type=Path, help="windows cache whose split gives the reference takes")
    p.add_argument("--split", default="test", help="reference split (default test)")
    p.add_argument("--real", type=Path, help="one folder holding every real recording's clips (default: each "
                   "in its Debian package's folder)")
    p.add_argument("--labelled", type=Path, metavar="MANIFEST",
                   help="score emotion-labelled real speech instead (a manifest of `emogesture labelled-speech`): "
                   "each speaker's recordings of an emotion, heard as that emotion")
    p.add_argument("--labelled-split", default="val", choices=["train", "val", "test"],
                   help="which speakers of --labelled (default val)")
    p.add_argument("--seeds", type=int, default=4, help="sampling seeds pooled for the motion (default 4)")
    p.add_argument("--out", required=True, type=Path, help="output folder (real_speech.json, real_speech.md)")
    p.add_argument("--overwrite", action="store_true", help="replace existing reports")
    p.set_defaults(func=run_evaluate_real)

    p = sub.add_parser("motion-stats", help="how lively and how human motion is: joint speeds, hands, posture, "
                       "fingers, body turn, onset coupling",
                       description="Statistics of SMPL-X motion (BEAT2 npz): per-joint angular speed, wrist speed "
                       "(mean, 95th percentile), and the share of frames with a wrist below the pelvis, an elbow "
                       "opened beyond 150 degrees, a wrist slower than 0.05 m/s, a hand at least 0.15 m in front "
                       "of the chest (the body's own frame), the wrists' median distance, their height above the "
                       "pelvis and the share of frames with the hands together; finger curl and how the hand shape "
                       "changes; the body's turn (the root's rotation about its mean) and the chest's yaw and pitch; "
                       "and, for files with their speech (NAME.wav beside NAME.npz, or a BEAT2 root's wave16k/), "
                       "how tightly arm speed follows the speech's onsets. One column per SOURCE.")
    p.add_argument("sources", nargs="+", metavar="[NAME=]SOURCE",
                   help="a BEAT2 root, a folder of .npz files or one .npz file (loose .npz files form one column)")
    p.add_argument("--every", type=int, default=1, help="use every N-th file of each source (default 1)")
    p.add_argument("--json", type=Path, help="also write the numbers as JSON here")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --json file")
    p.set_defaults(func=run_motion_stats)

    info = sub.add_parser("model-info", help="the bundled model, or parameter counts and FLOPs of a preset",
                          description="Without MODEL: the bundled model (files, checksums, training, numbers). "
                          "With MODEL: parameter counts and FLOPs of a preset.")
    info.set_defaults(func=run_model_info_bundled)
    isub = info.add_subparsers(dest="model", required=False, metavar="MODEL")
    p = isub.add_parser("speech", help="the speech disentanglement model")
    p.add_argument("--preset", default="paper", choices=["paper", "tiny"])
    p.add_argument("--speakers", type=int, default=30, help="speaker classes (default 30, BEAT)")
    p.set_defaults(func=run_model_info_speech)
    p = isub.add_parser("gesture", help="the gesture generator (motion prior + latent denoiser)")
    p.add_argument("--preset", default="paper", choices=["paper", "tiny"])
    p.add_argument("--variant", default="joint", choices=["joint", "disjoint", "no_prior", "no_audio"])
    p.set_defaults(func=run_model_info_gesture)


def run_evaluate_speech(args: argparse.Namespace) -> int:
    from emogesture.eval.speech import evaluate_speech, speech_markdown

    result = evaluate_speech(args.run, args.data, args.split, args.out, args.quadruples, args.seed,
                             overwrite=args.overwrite)
    print(speech_markdown(result))
    return 0


def run_evaluate_gesture(args: argparse.Namespace) -> int:
    from emogesture.errors import EmogestureError
    from emogesture.eval.gesture import evaluate_gesture, gesture_markdown

    sources = _named_paths(args.source, "--source", "NAME=FOLDER")
    if not args.model and (args.long_audio is not None or args.edit_model is not None):
        raise EmogestureError("--long-audio and --edit-model need --model (they generate with a trained model)")
    if args.model:
        from emogesture.eval.gesture_models import evaluate_gesture_models, gesture_models_markdown

        if sources or args.no_baselines:
            raise EmogestureError("--model cannot be combined with --source or --no-baselines")
        models = _named_paths(args.model, "--model", "NAME=RUN")
        if args.edit_model is not None and args.edit_model not in models:
            raise EmogestureError(f"--edit-model {args.edit_model!r} is not one of the --model names")
        result = evaluate_gesture_models(args.data, args.extractor, models, args.out, args.split, args.edit_model,
                                         args.seed, 65.0 if args.long_audio is None else args.long_audio,
                                         overwrite=args.overwrite)
        print(gesture_models_markdown(result))
        return 0
    result = evaluate_gesture(args.data, args.extractor, sources, args.out, args.split,
                              baselines=not args.no_baselines, seed=args.seed, overwrite=args.overwrite)
    print(gesture_markdown(result))
    return 0


def _named_paths(items: list[str], flag: str, shape: str) -> dict[str, Path]:
    from emogesture.errors import EmogestureError

    out: dict[str, Path] = {}
    for item in items:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise EmogestureError(f"{flag} {item!r}: expected {shape}")
        if name in out:
            raise EmogestureError(f"{flag}: the name {name!r} is given twice")
        out[name] = Path(path)
    return out


def run_evaluate_real(args: argparse.Namespace) -> int:
    from emogesture.eval.real_speech import evaluate_real_speech, real_speech_markdown

    result = evaluate_real_speech(args.model, args.data, args.out, args.split, args.real, args.seeds, args.overwrite,
                                  labelled=args.labelled, labelled_split=args.labelled_split)
    print(real_speech_markdown(result), end="")
    print(f"wrote {args.out / 'real_speech.json'} and {args.out / 'real_speech.md'}")
    return 0


def run_motion_stats(args: argparse.Namespace) -> int:
    import json

    from emogesture.errors import EmogestureError
    from emogesture.eval.motion_stats import file_statistics, motion_stats_markdown, named_sources
    from emogesture.fileio import atomic_output, check_output

    if args.every < 1:
        raise EmogestureError(f"--every {args.every}: must be at least 1")
    if args.json is not None:
        check_output(args.json, args.overwrite)
    sources = named_sources(args.sources)
    results = {name: file_statistics(files, args.every, progress=True) for name, files in sources.items()}
    print(motion_stats_markdown(results), end="")
    if args.json is not None:
        with atomic_output(args.json, args.overwrite) as tmp:
            tmp.write_text(json.dumps(results, indent=1))
        print(f"wrote {args.json}")
    return 0


def run_model_info_bundled(args: argparse.Namespace) -> int:
    import json

    from emogesture.assets import BUNDLED_MODEL
    from emogesture.bundle import verify_checksums
    from emogesture.checkpoints import load_model

    names = verify_checksums(BUNDLED_MODEL)
    print(f"bundled model: {BUNDLED_MODEL}")
    print(f"files (checksums match {BUNDLED_MODEL / 'SHA256SUMS'}):")
    for name in names:
        print(f"  {name:<26}{(BUNDLED_MODEL / name).stat().st_size / 1e6:>8.2f} MB")
    for kind in ("speech", "gesture", "extractor"):
        if not (BUNDLED_MODEL / f"{kind}.json").is_file():
            continue
        m = load_model(BUNDLED_MODEL / f"{kind}.json", kind)
        params = sum(p.numel() for p in m.model.parameters())
        step, splits = m.metadata.step, m.metadata.train_splits
        print(f"{kind:<10} {params:>10,} parameters, trained {'?' if step is None else step} steps"
              + (f" on {'+'.join(splits)}" if splits is not None else ""))
    card = BUNDLED_MODEL / "card.json"
    if card.is_file():
        numbers = json.loads(card.read_text())
        print(f"held-out numbers ({numbers.get('split', 'test')} split of the default synthetic corpus; "
              f"see {BUNDLED_MODEL / 'MODEL_CARD.md'}):")
        for key, value in numbers.get("metrics", {}).items():
            print(f"  {key:<30}{value:>10.3f}" if isinstance(value, (int, float)) else f"  {key:<30}{value:>10}")
    return 0


def run_model_info_speech(args: argparse.Namespace) -> int:
    import torch

    from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig, flops_per_window

    config = SpeechModelConfig.preset(args.preset, num_speakers=args.speakers)
    with torch.device("meta"):
        model = SpeechDisentangler(config)
    counts = model.count_parameters()
    flops = flops_per_window(config)
    print(f"speech disentanglement model, preset {args.preset} ({args.speakers} speakers)")
    print(f"{'component':<18}{'parameters':>16}{'GFLOPs / 10-s window':>24}")
    for name, n in counts.items():
        f = flops.get(name)
        print(f"{name:<18}{n:>16,}{(f'{f / 1e9:.3f}' if f is not None else '-'):>24}")
    print("FLOPs counted by torch.utils.flop_counter (a multiply-add is 2 FLOPs): encode + self-reconstruction.")
    return 0


def run_model_info_gesture(args: argparse.Namespace) -> int:
    import torch

    from emogesture.models.generation import GenerationConfig
    from emogesture.models.gesture import GestureModel, GestureModelConfig, gesture_flops

    config = GestureModelConfig.preset(args.preset, args.variant)
    with torch.device("meta"):
        model = GestureModel(config)
    counts = model.count_parameters()
    flops = gesture_flops(config)
    print(f"gesture model, preset {args.preset}, variant {args.variant} "
          f"({config.vae.frames} frames x {config.vae.feature_dim} features, z in R^{config.vae.latent_dim})")
    print(f"{'component':<12}{'parameters':>16}{'GFLOPs':>12}  per")
    per = {"prior": "encode + decode of one window", "denoiser": "one denoising step",
           "audio_ae": "one window"}
    for name, n in counts.items():
        f = flops.get(name)
        print(f"{name:<12}{n:>16,}{(f'{f / 1e9:.3f}' if f is not None else '-'):>12}  {per.get(name, '')}")
    steps = GenerationConfig.preset(args.preset, args.variant).num_inference_steps
    total = flops["decode"] + steps * flops["denoiser"] + flops.get("audio_ae", 0)
    print(f"generating one 10-s window ({steps} DDIM steps + decoding): {total / 1e9:.2f} GFLOPs")
    print("FLOPs counted by torch.utils.flop_counter (a multiply-add is 2 FLOPs).")
    return 0
