"""Every option the configs hold is used: turned on by a preset, set by the shipped recipe, or a documented user
option. An option tried and not adopted keeps its report, not its field (a stored config that held it at its
off value still reads; see ``config.from_dict``)."""

import dataclasses
import itertools
import re
from pathlib import Path

import pytest

from emogesture.config import from_dict, to_dict
from emogesture.errors import ConfigError
from emogesture.data.prepare import PrepareConfig
from emogesture.data.synthetic.corpus import CorpusConfig
from emogesture.models.generation import GenerationConfig
from emogesture.models.motion_vae import MotionVAEConfig
from emogesture.train.extractor import ExtractorTrainConfig
from emogesture.train.gesture import GestureTrainConfig
from emogesture.train.speech import SpeechTrainConfig

ROOT = Path(__file__).resolve().parents[1]
RECIPE = [ROOT / "experiments" / "recipe.sh", ROOT / "experiments" / "common.sh"]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SIZES = ("tiny", "paper")
PRESETS = {
    "speech": (SpeechTrainConfig, [SpeechTrainConfig.preset(s, loss) for s in SIZES for loss in ("full", "adversarial")]),
    "gesture": (GestureTrainConfig, [GestureTrainConfig.preset(s, v) for s in SIZES
                                     for v in ("joint", "disjoint", "no_prior", "no_audio")]),
    "extractor": (ExtractorTrainConfig, [ExtractorTrainConfig.preset(s) for s in SIZES]),
    "generation": (GenerationConfig, [GenerationConfig.preset(s, v) for s in SIZES for v in ("joint", "no_audio")]),
    "prepare": (PrepareConfig, [PrepareConfig()]),
    "corpus": (CorpusConfig, [CorpusConfig()]),
}
#: Options that start off and that no preset or the recipe turns on: each a documented user option (the key
#: must appear in the README or docs/), with why it stays.
DOCUMENTED = {
    "speech.model.encoder.dropout": "a regularisation a researcher sets for the paper preset on BEAT2",
    "speech.model.emotion_speaker_context": "documented with the measurement that it helps (docs/presets.md)",
    "speech.wave.codec": "a recording condition of the augmentation a user can turn on",
    "speech.num_workers": "data loading workers",
    "speech.level_jitter_db": "each training window heard at its own level (docs/training.md), measured on val",
    "gesture.num_workers": "data loading workers",
    "extractor.num_workers": "data loading workers",
    "gesture.weight_decay": "the optimiser's decay, the paper's 0",
    "gesture.model.diffusion.clip_sample": "a DDIM scheduler setting (the paper's: off)",
    "gesture.model.diffusion.set_alpha_to_one": "a DDIM scheduler setting (the paper's: off)",
    "gesture.model.diffusion.eta": "DDIM's η (the paper's deterministic 0)",
    "gesture.generation.output_smoothing": "a generation setting (docs/design.md)",
    "generation.output_smoothing": "a generation setting (docs/design.md)",
    "prepare.fbank.dither": "a Kaldi fbank option (the paper's features: off)",
    "prepare.fbank.high_freq": "a Kaldi fbank option (0: the Nyquist frequency)",
    "prepare.fbank.use_energy": "a Kaldi fbank option (the paper's features: off)",
    "prepare.fbank.energy_floor": "a Kaldi fbank option",
    "prepare.features.include_translation": "the root translation as motion features, for BEAT2 training",
    "corpus.seed": "the synthetic corpus's seed (`emogesture corpus --seed`)",
}
#: Tried, not adopted, removed: their reports are in the experiments' topic folders (experiments/README.md).
RETIRED = ["model.vae.frames_per_token", "model.vae.latent_tokens", "model.vae.decoder_smoothing",
           "model.denoiser.timing_tokens", "losses.vspeed", "losses.vaccel", "losses.align_speed",
           "losses.align_accel", "losses.wrist_features", "losses.finger_features", "real_neutral",
           "real_neutral_weight", "real_neutral_pull", "real_emotion_share", "emotion_scramble",
           "emotion_scramble_share", "real_labelled", "real_labelled_weight",
           "speaker_prosody_scale"]


def flat(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict) and v:
            out.update(flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def is_off(value) -> bool:
    return value in (0, 0.0, False, "", None) or value == [] or value == {}


def fields():
    """(name, key, default value, whether any preset turns it on) of every leaf option."""
    for name, (cls, presets) in PRESETS.items():
        base = flat(to_dict(cls()))
        on = {k for p in presets for k, v in flat(to_dict(p)).items() if not is_off(v)}
        on |= {k for a, b in itertools.combinations(presets, 2) for k, v in flat(to_dict(a)).items()
               if flat(to_dict(b)).get(k) != v}
        for key, value in base.items():
            yield name, key, value, key in on


def test_every_option_that_starts_off_is_turned_on_by_a_preset_the_recipe_or_is_documented():
    recipe = "\n".join(p.read_text() for p in RECIPE)
    docs = "\n".join(p.read_text() for p in DOCS)
    unused, undocumented = [], []
    for name, key, value, on in fields():
        if not is_off(value) or on:
            continue
        leaf = key.split(".")[-1]
        if re.search(rf"\b{re.escape(key)}=", recipe) or re.search(rf"--{leaf.replace('_', '-')}\b", recipe):
            continue
        if f"{name}.{key}" not in DOCUMENTED:
            unused.append(f"{name}.{key}")
        elif leaf not in docs:
            undocumented.append(f"{name}.{key}")
    assert not unused, f"options no preset, recipe or documented user option turns on: {unused}"
    assert not undocumented, f"listed as documented, but no README or docs page names them: {undocumented}"
    known = {f"{name}.{key}" for name, key, _, _ in fields()}
    assert not set(DOCUMENTED) - known, f"stale entries: {sorted(set(DOCUMENTED) - known)}"


def test_retired_options_are_gone_and_a_stored_config_at_their_off_value_still_reads():
    known = {key for _, key, _, _ in fields()}
    assert not [r for r in RETIRED if r in known]
    old = {**to_dict(MotionVAEConfig()), "frames_per_token": 1, "latent_tokens": 1, "decoder_smoothing": 0.0}
    assert from_dict(MotionVAEConfig, old) == MotionVAEConfig()
    with pytest.raises(ConfigError, match="decoder_smoothing = 1.0: this option was removed"):
        from_dict(MotionVAEConfig, {**old, "decoder_smoothing": 1.0})
    assert dataclasses.fields(MotionVAEConfig)  # a dataclass still
