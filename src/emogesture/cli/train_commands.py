"""``emogesture train ...``: one command shape for every model."""

from __future__ import annotations

import argparse
from pathlib import Path



def _engine_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", required=True, type=Path, help="windows cache from `emogesture prepare`")
    p.add_argument("--out", required=True, type=Path, help="run folder (re-running the same command resumes)")
    p.add_argument("--config", type=Path, help="YAML file of training settings (merged over the preset)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a setting, e.g. --set lr=1e-4 --set model.encoder.depth=4")
    p.add_argument("--steps", type=int, default=1000, help="total optimisation steps (default 1000)")
    p.add_argument("--devices", type=int, default=1, help="processes / GPUs; >1 uses DDP")
    p.add_argument("--device", "--accelerator", dest="accelerator", default="cpu",
                   choices=["cpu", "cuda", "gpu", "auto"], help="cpu (default), cuda (= gpu) or auto")
    p.add_argument("--precision", default="32-true", choices=["32-true", "fp32", "bf16-mixed", "bf16"],
                   help="32-true (= fp32, default; on GPUs its matrix products use TF32) or bf16-mixed "
                        "(= bf16: autocast, float32 weights)")
    p.add_argument("--checkpoint-every", type=int, default=200, help="steps between checkpoints (default 200)")
    p.add_argument("--log-every", type=int, default=20, help="steps between logged losses (default 20)")
    p.add_argument("--seed", type=int, default=0, help="seed of weights, sampling and augmentation")
    p.add_argument("--overwrite", action="store_true", help="start the run folder again from scratch")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def register(sub: argparse._SubParsersAction) -> None:
    train = sub.add_parser("train", help="train a model (speech)")
    tsub = train.add_subparsers(dest="model", required=True, metavar="MODEL")
    p = tsub.add_parser("speech", help="the speech disentanglement model (content / emotion / style)")
    p.add_argument("--preset", default="tiny", choices=["tiny", "paper"], help="model size (default tiny)")
    p.add_argument("--losses", default="full", choices=["full", "emotion_only", "style_only", "adversarial"],
                   help="loss terms: full (the paper), emotion_only / style_only (its ablations), adversarial (full + latent adversaries)")
    p.add_argument("--init-from", type=Path, metavar="WEIGHTS",
                   help="start the three audio encoders from DeiT weights you have (timm layout, .safetensors or "
                        ".pth, e.g. deit_base_distilled_patch16_384; with --preset paper), as the paper does; "
                        "or start the whole model from a trained speech model (its run folder) of the same "
                        "architecture, to train it on with other settings")
    _engine_args(p)
    p.set_defaults(func=run_train_speech)
    p = tsub.add_parser("extractor", help="the motion feature extractor M used by the gesture metrics")
    p.add_argument("--preset", default="tiny", choices=["tiny", "paper"], help="model size (default tiny)")
    _engine_args(p)
    p.set_defaults(func=run_train_extractor)
    p = tsub.add_parser("gesture", help="the gesture generator: motion prior + latent diffusion (joint training)")
    p.add_argument("--preset", default="tiny", choices=["tiny", "paper"], help="model size (default tiny)")
    p.add_argument("--variant", default="joint", choices=["joint", "disjoint", "no_prior", "no_audio"],
                   help="joint (the paper's model) or one of its ablations")
    p.add_argument("--speech", type=Path, help="run folder of `emogesture train speech` (all variants but no_audio)")
    _engine_args(p)
    p.set_defaults(func=run_train_gesture)
    p = tsub.add_parser("bundle", help="every stage of a recipe (configs/bundled.yaml: the bundled model's), "
                        "calibrated and bundled",
                        description="Train a recipe's stages in order, each in its own folder under --out (a finished "
                        "stage is kept, an interrupted one resumes), calibrate the emotion perception and the "
                        "fallback style, and write the bundle to OUT/bundle.")
    p.add_argument("--recipe", required=True, type=Path, help="the recipe, e.g. configs/bundled.yaml")
    p.add_argument("--data", required=True, type=Path, help="windows cache from `emogesture prepare`")
    p.add_argument("--out", required=True, type=Path, help="run folder (re-running the same command resumes)")
    p.add_argument("--labelled-root", type=Path, metavar="RAVDESS",
                   help="RAVDESS's audio_speech_actors_01-24 folder: with the recipe's perception.front_end, "
                        "its train actors teach the front end's read-out beside the corpus (CC BY-NC-SA 4.0: the "
                        "weights are then for non-commercial use)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=run_train_bundle)

    cal = sub.add_parser("calibrate", help="measure a model's calibrations on held-out windows")
    csub = cal.add_subparsers(dest="model", required=True, metavar="MODEL")
    p = _calibrate_parser(csub, "gesture", "the gesture generator's residual noise (written as a new model folder)",
                          "run folder of `emogesture train gesture`", "the calibrated copy of the model",
                          "held-out cache split to measure on (default val)")
    p.add_argument("--seed", type=int, default=0, help="seed of the samples measured (default 0)")
    p.add_argument("--scale", type=float, default=1.0, help="residual noise scale stored with the model (default 1)")
    p.set_defaults(func=run_calibrate_gesture)
    p = _calibrate_parser(csub, "speech", "the speech model's emotion perception (for generate --emotion auto)",
                          "run folder of `emogesture train speech`", "the calibrated copy of the model",
                          "held-out split for the trust threshold (default val)")
    p.add_argument("--quantile", type=float, default=0.99,
                   help="quantile of the held-out distances used as the trust threshold (default 0.99)")
    p.add_argument("--real-voices", type=_names, default=[], metavar="NAME,...",
                   help="real training voices (e.g. fr_june,it_carlo,ru_ivr) given each of the synthetic corpus's "
                        "emotions, each emotion of theirs read by its own mean beside the corpus's")
    p.add_argument("--condition-means", type=_names, default=[], metavar="CONDITION,...",
                   help="also read each emotion by its means of the train takes heard through these recording "
                        "conditions: telephone (a telephone band), quieter (6-14 dB), noisy (white noise, 8-16 dB "
                        "SNR) (the read-out only; the trust and the latents animated are unchanged)")
    p.set_defaults(func=run_calibrate_speech)
    p = _calibrate_parser(csub, "style", "the gesture model's fallback style for unfamiliar voices (--emotion auto)",
                          "gesture model (run folder or .json)", "the copy of the model with its fallback style",
                          "held-out cache split to choose on (default val)",
                          description="Choose, on held-out windows, the training speaker whose style gives the "
                          "gesture model's typical motion; unfamiliar voices are blended toward it under --emotion auto.")
    p.add_argument("--seed", type=int, default=0, help="seed of the samples compared (default 0)")
    p.add_argument("--windows", type=int, default=96, help="held-out windows generated per speaker (default 96)")
    p.set_defaults(func=run_calibrate_style)

    p = sub.add_parser("bundle", help="put a speech, gesture and extractor model into one folder (float16)",
                       description="Copy the models into OUT as speech.*, gesture.*, extractor.* with float16 "
                       "weights and a SHA256SUMS list, as the package's bundled model is stored.")
    p.add_argument("--speech", required=True, type=Path, help="speech model (run folder or .json)")
    p.add_argument("--gesture", required=True, type=Path, help="gesture model trained on that speech model")
    p.add_argument("--extractor", type=Path, help="motion feature extractor of the evaluation suite")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--set", dest="generation", action="append", default=[], metavar="KEY=VALUE",
                   help="change a generation setting of the gesture model (repeatable; no retraining): "
                        "num_inference_steps, residual_scale, timing_guidance, timing_guidance_on, "
                        "output_smoothing, output_lowpass_hz, seam_candidates, hop_seconds, noise_suppression, "
                        "perception_semitones")
    p.add_argument("--overwrite", action="store_true", help="write into a folder that is not empty")
    p.set_defaults(func=run_bundle)


def _options(args: argparse.Namespace):
    from emogesture.train.runs import RunOptions

    return RunOptions(steps=args.steps, devices=args.devices, accelerator=args.accelerator, precision=args.precision,
                      checkpoint_every=args.checkpoint_every, log_every=args.log_every, seed=args.seed,
                      overwrite=args.overwrite, progress=not args.quiet)


def _report(what: str, run) -> int:
    if run.exported:
        print(f"{what}: {run.model} (step {run.step})")
    return 0


def run_train_speech(args: argparse.Namespace) -> int:
    from emogesture.train.runs import train_speech

    return _report("speech model", train_speech(args.data, args.out, preset=args.preset, losses=args.losses,
                                                config_file=args.config, overrides=args.overrides,
                                                init_from=args.init_from, options=_options(args)))


def run_train_extractor(args: argparse.Namespace) -> int:
    from emogesture.train.runs import train_extractor

    return _report("motion feature extractor", train_extractor(args.data, args.out, preset=args.preset,
                                                               config_file=args.config, overrides=args.overrides,
                                                               options=_options(args)))


def _names(text: str) -> list[str]:
    """A comma-separated list of names (``fr_june, it_carlo``) -> the names."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise argparse.ArgumentTypeError(f"{text!r}: give one or more names separated by commas")
    return names


def _calibrate_parser(sub, name: str, help_text: str, model_help: str, out_what: str, split_help: str,
                      description: str | None = None) -> argparse.ArgumentParser:
    """A ``calibrate`` subcommand with the arguments every calibration takes."""
    p = sub.add_parser(name, help=help_text, description=description)
    p.add_argument("--model", required=True, type=Path, help=model_help)
    p.add_argument("--data", required=True, type=Path, help="windows cache from `emogesture prepare`")
    p.add_argument("--out", required=True, type=Path, help=f"folder for {out_what}")
    p.add_argument("--split", default="val", help=split_help)
    p.add_argument("--overwrite", action="store_true", help="replace a model already in --out")
    return p


def run_train_gesture(args: argparse.Namespace) -> int:
    from emogesture.train.runs import train_gesture

    return _report("gesture model", train_gesture(args.data, args.out, speech=args.speech, preset=args.preset,
                                                  variant=args.variant, config_file=args.config,
                                                  overrides=args.overrides, options=_options(args)))


def run_train_bundle(args: argparse.Namespace) -> int:
    from emogesture.train.recipe import build_bundle, load_recipe

    out = build_bundle(load_recipe(args.recipe), args.data, args.out, labelled_root=args.labelled_root,
                       progress=not args.quiet)
    print(f"bundle: {out}")
    return 0


def run_calibrate_gesture(args: argparse.Namespace) -> int:
    from emogesture.train.gesture import calibrate_run

    stats = calibrate_run(args.model, args.data, args.out, args.split, args.seed, args.overwrite, args.scale)
    print(f"gesture model calibrated on {stats['windows']} {args.split} windows (residual variance "
          f"{stats['residual_variance']:.4f}, latent variance {stats['latent_variance']:.4f}, "
          f"shrinkage {stats['shrinkage']:.3f}): {args.out / 'model.json'}")
    return 0


def run_calibrate_speech(args: argparse.Namespace) -> int:
    from emogesture.train.perception import calibrate_perception_run

    p = calibrate_perception_run(args.model, args.data, args.out, args.split, args.quantile, args.overwrite,
                                 real_voices=args.real_voices, condition_means=args.condition_means)
    print(f"emotion perception calibrated: means and spread of {p.info['train_windows']} train windows; thresholds "
          f"emotion {p.emotion.threshold:.3f}, voice {p.voice.threshold:.3f} (quantile {p.info['quantile']:g} of "
          f"{p.info['held_out_windows']} {args.split} windows), read-out temperature {p.temperature:.2f}"
          + (f"; the real voices {', '.join(args.real_voices)} given each emotion ({p.info['real_windows']} windows)"
             if args.real_voices else "")
          + (f"; each emotion heard {', '.join(args.condition_means)} ({p.info['band_windows']} train windows)"
             if args.condition_means else "") + ": "
          f"{args.out / 'model.json'}")
    return 0


def run_calibrate_style(args: argparse.Namespace) -> int:
    from emogesture.train.fallback_style import calibrate_fallback_run

    r = calibrate_fallback_run(args.model, args.data, args.out, args.split, args.seed, args.overwrite, args.windows)
    chosen, ref = r["candidates"][str(r["speaker"])], r["reference"]
    print(f"fallback style: training speaker {r['speaker']} (on {r['windows']} {args.split} windows: a hand in front "
          f"{chosen['in_front']:.0%} against {ref['in_front']:.0%} with the windows' own styles, wrists "
          f"{chosen['wrist_distance']:.2f} m against {ref['wrist_distance']:.2f} m): {args.out / 'model.json'}")
    return 0


def run_bundle(args: argparse.Namespace) -> int:
    from emogesture.bundle import bundle_models

    out = bundle_models(args.speech, args.gesture, args.extractor, args.out, args.overwrite,
                        generation=args.generation)
    for path in sorted(out.iterdir()):
        print(f"{path}  ({path.stat().st_size / 1e6:.2f} MB)")
    return 0
