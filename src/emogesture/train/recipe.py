"""The bundled model's recipe as a file (``configs/bundled.yaml``) and the one function that builds a bundle
from it (``emogesture train bundle``, which ``make model`` runs).

A recipe names its training stages in order (each a speech model, the extractor or the gesture model, with
its steps and the settings merged over the tiny preset, as ``--set KEY=VALUE`` would merge them), the
emotion perception's calibration, the labelled speech's actor split and the generation settings the bundle
ships with. :func:`build_bundle` runs every stage that is not finished yet (a stage folder whose model
reached its steps is kept; an interrupted one resumes from its checkpoint), calibrates, and bundles.

The stages are the same with or without labelled speech (RAVDESS), which feeds the front end's read-out only:
with ``perception.front_end``, the calibrated speech model's perception also gets the read-out of the front end
trained on real speech (:mod:`emogesture.train.heard_readout`), fitted on the corpus and the labelled speakers.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import yaml

from emogesture.errors import ConfigError, InputFileError

MODELS = ("speech", "extractor", "gesture")


@dataclass(frozen=True)
class Stage:
    """One training stage of a recipe."""

    name: str
    model: str  # speech, extractor or gesture
    steps: int
    settings: dict = field(default_factory=dict)  # KEY -> value, merged over the preset
    losses: str = "adversarial"  # speech models
    start_from: str | None = None  # a speech stage trained on from an earlier stage's model
    speech: str | None = None  # the gesture model's speech stage (None: the last speech stage before it)
    checkpoint_every: int = 100

    def overrides(self) -> list[str]:
        """The settings as ``KEY=VALUE`` overrides."""
        return [f"{key}={json.dumps(value) if isinstance(value, (list, dict, bool)) else value}"
                for key, value in self.settings.items()]


@dataclass(frozen=True)
class Recipe:
    """A bundle's recipe (module docstring)."""

    stages: tuple[Stage, ...]
    perception: dict
    labelled_speech: dict
    generation: dict

    def stage(self, name: str) -> Stage:
        for s in self.stages:
            if s.name == name:
                return s
        raise ConfigError(f"the recipe has no stage {name!r}")

    def speech_of(self, stage: Stage) -> Stage:
        """The speech stage a gesture stage trains on: its ``speech``, else the last speech stage before it."""
        if stage.speech is not None:
            return self.stage(stage.speech)
        before = [s for s in self.stages[: self.stages.index(stage)] if s.model == "speech"]
        if not before:
            raise ConfigError(f"recipe stage {stage.name!r}: no speech stage before it")
        return before[-1]

    def generation_overrides(self) -> list[str]:
        return [f"{k}={v}" for k, v in self.generation.items()]


def load_recipe(path: str | PathLike[str]) -> Recipe:
    """Read a recipe YAML file; every problem is a one-line error naming the file."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise InputFileError(path, f"cannot read the recipe ({e.strerror or e})") from None
    except yaml.YAMLError as e:
        raise InputFileError(path, f"not valid YAML ({str(e).splitlines()[0]})") from None
    if not isinstance(data, dict) or not isinstance(data.get("stages"), list):
        raise InputFileError(path, "a recipe holds a mapping with a list of stages")
    stages, names = [], set()
    for raw in data["stages"]:
        raw = dict(raw)
        if "from" in raw:
            raw["start_from"] = raw.pop("from")
        try:
            stage = Stage(**raw)
        except TypeError as e:
            raise InputFileError(path, f"stage {raw.get('name')!r}: {e}") from None
        if stage.model not in MODELS:
            raise InputFileError(path, f"stage {stage.name!r}: model must be one of {', '.join(MODELS)}")
        if stage.name in names:
            raise InputFileError(path, f"stage {stage.name!r} comes twice")
        for ref in (stage.start_from, stage.speech):
            if ref is not None and ref not in names:
                raise InputFileError(path, f"stage {stage.name!r}: {ref!r} is not an earlier stage")
        names.add(stage.name)
        stages.append(stage)
    perception = dict(data.get("perception") or {})
    if perception.get("front_end") not in (None, "whisper"):
        raise InputFileError(path, f"perception.front_end {perception['front_end']!r}: the one known is 'whisper'")
    from emogesture.data.real_speech import TRAINING_VOICES

    unknown = [v for v in perception.get("front_end_neutral_voices", ()) if v not in TRAINING_VOICES]
    if unknown:
        raise InputFileError(path, f"perception.front_end_neutral_voices: {', '.join(map(str, unknown))} not among "
                                   f"the training voices ({', '.join(TRAINING_VOICES)})")
    from emogesture.train.perception import CONDITIONS

    unknown = [c for c in perception.get("condition_means", ()) if c not in CONDITIONS]
    if unknown:
        raise InputFileError(path, f"perception.condition_means: {', '.join(map(str, unknown))} not among the "
                                   f"conditions ({', '.join(CONDITIONS)})")
    return Recipe(tuple(stages), perception, dict(data.get("labelled_speech") or {}), dict(data.get("generation") or {}))


def finished(run: Path, steps: int) -> bool:
    """Whether the stage folder ``run`` holds its exported model at ``steps``."""
    try:
        return json.loads((run / "model.json").read_text())["extra"]["step"] >= steps
    except (OSError, ValueError, KeyError, TypeError):
        return False


def labelled_manifest(recipe: Recipe, root: str | PathLike[str], out: Path, calm: str | None = None) -> Path:
    """The labelled-speech manifest of the recordings under ``root`` (RAVDESS's layout) with the recipe's
    actor split, at ``out`` unless it is there; ``calm``: how calm is taken (the recipe's by default)."""
    from emogesture.data.labelled_speech import assign_speaker_splits, manifest_text, scan_layout
    from emogesture.fileio import atomic_output

    if out.exists():
        return out
    spec = recipe.labelled_speech
    clips = assign_speaker_splits(scan_layout(spec.get("layout", "ravdess"), root, calm or spec.get("calm", "drop")),
                                  list(spec["val_speakers"]), list(spec["test_speakers"]))
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(out, overwrite=False) as tmp:
        tmp.write_text(manifest_text(clips, out.resolve().parent), encoding="utf-8")
    return out


def build_bundle(recipe: Recipe, cache: str | PathLike[str], run: str | PathLike[str], *,
                 labelled_root: str | PathLike[str] | None = None, progress: bool = True,
                 report=print) -> Path:
    """Train, calibrate and bundle ``recipe`` on the windows cache ``cache`` into ``run`` (each stage in its
    own folder, the bundle in ``run/bundle``); ``labelled_root``: RAVDESS's ``audio_speech_actors_01-24``
    folder (with ``perception.front_end``, its train actors teach the front end's read-out). Every finished
    step is kept; each training's wall time is appended to ``run/times.txt``. Returns the bundle folder."""
    from emogesture.bundle import bundle_models
    from emogesture.train.fallback_style import calibrate_fallback_run
    from emogesture.train.perception import calibrate_perception_run
    from emogesture.train.runs import RunOptions, train_extractor, train_gesture, train_speech

    run = Path(run)
    run.mkdir(parents=True, exist_ok=True)
    labelled = (labelled_manifest(recipe, labelled_root, run / "labelled.csv") if labelled_root is not None
                else None)
    for stage in recipe.stages:
        out = run / stage.name
        if finished(out, stage.steps):
            continue
        report(f"{stage.name}: {stage.model} model, {stage.steps} steps")
        options = RunOptions(steps=stage.steps, checkpoint_every=stage.checkpoint_every, progress=progress)
        overrides = stage.overrides()
        start = time.time()
        if stage.model == "speech":
            train_speech(cache, out, losses=stage.losses, overrides=overrides, options=options,
                         init_from=run / stage.start_from if stage.start_from else None)
        elif stage.model == "extractor":
            train_extractor(cache, out, overrides=overrides, options=options)
        else:
            speech = run / recipe.speech_of(stage).name
            train_gesture(cache, out, speech=speech, overrides=overrides, options=options)
        with (run / "times.txt").open("a") as f:
            f.write(f"{stage.name}: {time.time() - start:.0f} s\n")
    speech = run / [s for s in recipe.stages if s.model == "speech"][-1].name
    gesture = run / [s for s in recipe.stages if s.model == "gesture"][-1].name
    extractor = [s for s in recipe.stages if s.model == "extractor"]
    perception = recipe.perception
    if not (run / "speech_calibrated" / "model.json").exists():
        calibrate_perception_run(speech, cache, run / "speech_calibrated",
                                 condition_means=tuple(perception.get("condition_means", ())),
                                 real_voices=tuple(perception.get("real_voices", ())))
    if perception.get("front_end") and labelled is not None and not (run / "speech_heard" / "model.json").exists():
        from emogesture.train.heard_readout import calibrate_heard_run

        calibrate_heard_run(run / "speech_calibrated", cache, labelled, run / "speech_heard",
                            neutral_voices=tuple(perception.get("front_end_neutral_voices", ())))
    heard = run / ("speech_heard" if perception.get("front_end") and labelled is not None else "speech_calibrated")
    if not (run / "gesture_styled" / "model.json").exists():
        calibrate_fallback_run(gesture, cache, run / "gesture_styled")
    return bundle_models(heard, run / "gesture_styled",
                         run / extractor[-1].name if extractor else None, run / "bundle", overwrite=True,
                         generation=recipe.generation_overrides())
