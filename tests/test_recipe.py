"""The bundled model's recipe as a file (configs/bundled.yaml): the bundled model holds its settings, the
experiment scripts' copies of them agree, and a recipe builds a bundle (a smoke version of `make model`)."""

import json
import re
from dataclasses import asdict
from pathlib import Path

import pytest

from emogesture.assets import bundled_model_file
from emogesture.checkpoints import load_model
from emogesture.config import load_config, to_dict
from emogesture.data.beat import write_split_csv
from emogesture.data.prepare import prepare
from emogesture.errors import InputFileError
from emogesture.train.recipe import build_bundle, finished, load_recipe

from helpers import make_root

ROOT = Path(__file__).resolve().parents[1]
RECIPE = ROOT / "configs" / "bundled.yaml"


def stage_config(recipe, stage):
    """A stage's training config, as `emogesture train` builds it."""
    from emogesture.train.gesture import GestureTrainConfig
    from emogesture.train.speech import SpeechTrainConfig

    overrides = stage.overrides()
    if stage.model == "speech":
        return load_config(SpeechTrainConfig, None, overrides, base=to_dict(SpeechTrainConfig.preset("tiny", stage.losses)))
    return load_config(GestureTrainConfig, None, overrides, base=to_dict(GestureTrainConfig.preset("tiny", "joint")))


def test_the_bundled_model_holds_the_recipe():
    recipe = load_recipe(RECIPE)
    speech_file = json.loads(bundled_model_file("speech").read_text())
    speech_stage = [s for s in recipe.stages if s.model == "speech"][-1]
    expected = to_dict(stage_config(recipe, speech_stage).model)
    expected["num_speakers"] = speech_file["config"]["num_speakers"]  # the cache's train speakers, at training
    assert speech_file["config"] == expected
    assert speech_file["extra"]["step"] == speech_stage.steps
    perception = speech_file["extra"]["emotion_perception"]
    assert perception["info"].get("condition_means", []) == recipe.perception.get("condition_means", [])
    assert perception["info"].get("real_voices", []) == recipe.perception.get("real_voices", [])
    heard = perception.get("heard")  # the front end's read-out, with RAVDESS
    if heard is not None:
        assert recipe.perception.get("front_end") == "whisper" and heard["info"]["labelled"]
        assert heard["info"].get("neutral_voices", []) == recipe.perception.get("front_end_neutral_voices", [])
    gesture = load_model(bundled_model_file("gesture"), "gesture")
    gesture_stage = recipe.stage("gesture")
    assert to_dict(gesture.config) == to_dict(stage_config(recipe, gesture_stage).model)
    assert gesture.metadata.step == gesture_stage.steps
    expected = stage_config(recipe, gesture_stage).generation.with_overrides(recipe.generation_overrides())
    assert asdict(gesture.generation) == asdict(expected)
    extractor = json.loads(bundled_model_file("extractor").read_text())
    assert extractor["extra"]["step"] == recipe.stage("extractor").steps


def _array(text: str, name: str) -> list[str]:
    body = re.search(rf"^{name}=\((.*?)\)", text, re.S | re.M).group(1)
    return re.findall(r"--set (\S+)", body)


def test_the_experiment_scripts_copies_agree_with_the_recipe():
    """experiments/recipe.sh's --set arrays and common.sh's GENERATION are the recipe's settings."""
    recipe = load_recipe(RECIPE)
    shell = (ROOT / "experiments" / "recipe.sh").read_text()
    tuned = [o for name in ("SPEECH_HARD", "SPEECH_PITCH", "SPEECH_BAND", "SPEECH_VARIANTS") for o in _array(shell, name)]
    as_numbers = lambda items: {k: float(v) for k, v in (o.split("=") for o in items)}
    assert as_numbers(tuned) == as_numbers(recipe.stage("speech_tuned").overrides())
    generation = _array((ROOT / "experiments" / "common.sh").read_text(), "GENERATION")
    assert sorted(generation) == sorted(recipe.generation_overrides())
    split = re.search(r"^RAVDESS_SPLIT=\((.*?)\)", shell, re.M).group(1).split()
    assert split[1].split(",") == recipe.labelled_speech["val_speakers"]
    assert split[3].split(",") == recipe.labelled_speech["test_speakers"]


def test_a_broken_recipe_is_one_line_naming_the_file(tmp_path):
    bad = tmp_path / "r.yaml"
    for text, message in (("stages: [{name: a, model: face, steps: 1}]", "model must be one of"),
                          ("stages: [{name: a, model: speech, steps: 1, from: b}]", "'b' is not an earlier stage"),
                          ("stages: [{name: a, model: speech, step: 1}]", "stage 'a'"),
                          ("stages: 3", "a list of stages"), ("stages: [", "not valid YAML"),
                          ("stages: []\nperception: {front_end: whisper, front_end_neutral_voices: [words_en]}",
                           "words_en not among the training voices"),
                          ("stages: []\nperception: {condition_means: [telephone, loud]}",
                           "perception.condition_means: loud not among the conditions")):
        bad.write_text(text)
        with pytest.raises(InputFileError, match=message) as e:
            load_recipe(bad)
        assert str(bad) in str(e.value) and "\n" not in str(e.value)


SMOKE = """
stages:
  - {name: speech, model: speech, steps: 2, checkpoint_every: 1, settings: {batch_size: 2, samples_per_epoch: 64}}
  - {name: extractor, model: extractor, steps: 2, checkpoint_every: 1, settings: {batch_size: 4}}
  - name: gesture
    model: gesture
    steps: 2
    checkpoint_every: 1
    settings: {batch_size: 4, align_ddim_steps: 2, align_every: 1, prior_warmup_steps: 1,
               generation.num_inference_steps: 3}
perception: {condition_means: [], real_voices: []}
labelled_speech: {}
generation: {num_inference_steps: 2, seam_candidates: 1}
"""


@pytest.mark.training
def test_a_recipe_builds_a_bundle_and_a_second_run_trains_nothing(tmp_path):
    names = make_root(tmp_path / "root", speakers=(1, 2, 3), takes=(1, 2, 3, 4, 5, 65, 66, 67, 68, 69))
    split_of = {"3": "val", "67": "val", "4": "test", "68": "test"}
    write_split_csv(tmp_path / "root" / "train_test_split.csv",
                    {n: split_of.get(n.split("_")[3], "train") for n in names})
    prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    (tmp_path / "recipe.yaml").write_text(SMOKE)
    recipe = load_recipe(tmp_path / "recipe.yaml")
    bundle = build_bundle(recipe, tmp_path / "cache", tmp_path / "run", progress=False, report=lambda _: None)
    assert sorted(p.name for p in bundle.iterdir()) == sorted(
        ["SHA256SUMS", *(f"{m}.{x}" for m in ("speech", "gesture", "extractor") for x in ("json", "safetensors"))])
    assert all(finished(tmp_path / "run" / s.name, s.steps) for s in recipe.stages)
    assert load_model(bundle / "gesture.json", "gesture").generation.num_inference_steps == 2
    times = (tmp_path / "run" / "times.txt").read_text()
    assert [line.split(":")[0] for line in times.splitlines()] == ["speech", "extractor", "gesture"]
    build_bundle(recipe, tmp_path / "cache", tmp_path / "run", progress=False, report=lambda _: None)
    assert (tmp_path / "run" / "times.txt").read_text() == times  # every stage kept, nothing trained again
