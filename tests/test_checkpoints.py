"""Model files: round trip, atomic writes, and one-line errors for the wrong file."""

import json
import re
import subprocess
import sys

import pytest
import torch

from emogesture.checkpoints import (content_checksum, file_sha256, load_model, read_meta,
                                   save_model)
from emogesture.errors import ConfigError, InputFileError, OutputExistsError
from emogesture.models.extractor import ExtractorConfig, MotionFeatureExtractor
from emogesture.models.metadata import ExtractorMetadata, GestureMetadata


def _model(seed=0):
    torch.manual_seed(seed)
    return MotionFeatureExtractor(ExtractorConfig.preset("tiny"))


def test_round_trip_gives_the_same_outputs(tmp_path):
    model = _model().eval()
    save_model(tmp_path / "run", "extractor", model, model.config, {"motion_mean": [0.0, 1.0]})
    loaded = load_model(tmp_path / "run", "extractor")
    assert loaded.config == model.config and loaded.metadata.motion_mean == [0.0, 1.0]
    x = torch.randn(2, 300, 282, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        a, b = model(x), loaded.model(x)
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["model.json", "model.safetensors"]


def test_a_copy_saved_in_the_stored_type_keeps_a_bundles_float16_weights_byte_for_byte(tmp_path):
    from emogesture.checkpoints import stored_weights_dtype

    model = _model().eval()
    save_model(tmp_path / "run", "extractor", model, model.config, {"motion_mean": [0.0]})
    save_model(tmp_path / "half", "extractor", model, model.config, {"motion_mean": [0.0]}, weights_dtype=torch.float16)
    assert stored_weights_dtype(load_model(tmp_path / "run", "extractor")) is None
    half = load_model(tmp_path / "half", "extractor")
    assert stored_weights_dtype(half) == torch.float16
    save_model(tmp_path / "copy", "extractor", half.model, half.config, half.metadata,
               weights_dtype=stored_weights_dtype(half))  # what a calibration does with a bundle's model
    assert read_meta(tmp_path / "copy", "extractor")["weights_sha256"] == half.weights_sha256


def test_arrays_stored_beside_the_weights_come_back_exactly_and_keep_their_type(tmp_path):
    import numpy as np

    model = _model().eval()
    arrays = {"emotion_perception.emotion.means": np.random.default_rng(0).normal(size=(3, 5))}
    save_model(tmp_path / "run", "extractor", model, model.config, {}, weights_dtype=torch.float16, tensors=arrays)
    loaded = load_model(tmp_path / "run", "extractor")  # not read as weights the model lacks
    back = loaded.tensors["emotion_perception.emotion.means"]
    assert back.dtype == np.float64 and np.array_equal(back, arrays["emotion_perception.emotion.means"])
    with pytest.raises(ValueError, match="must begin with"):
        save_model(tmp_path / "bad", "extractor", model, model.config, {}, tensors={"head.weight": np.zeros(2)})


def test_loading_draws_no_random_weights_and_sets_every_one(tmp_path, monkeypatch):
    """A model built to be loaded is built on the meta device: no random fill runs and the global random
    stream is not touched; every weight is the file's, in the model's own type (float16 files load as
    float32); buffers computed from the config are the ones a fresh model computes (bit for bit); a gesture
    model whose file lacks its optional calibration gets that buffer's zeros; torch.nn.init is untouched."""
    from torch import nn

    from emogesture.models.gesture import GestureModel, GestureModelConfig

    model = _model().eval()
    save_model(tmp_path / "x", "extractor", model, model.config, weights_dtype=torch.float16)
    calls = []
    kaiming = nn.init.kaiming_uniform_
    monkeypatch.setattr(nn.init, "kaiming_uniform_",
                        lambda *a, **k: calls.append((a[0] if a else k["tensor"]).is_meta) or kaiming(*a, **k))
    torch.manual_seed(3)
    expected = torch.rand(4)
    torch.manual_seed(3)
    loaded = load_model(tmp_path / "x", "extractor")
    assert torch.equal(torch.rand(4), expected)  # nothing was drawn
    assert calls and all(calls)  # a fill only ever met a tensor without memory
    for k, v in model.state_dict().items():
        got = loaded.model.state_dict()[k]
        assert got.dtype == v.dtype and got.device.type == "cpu" and torch.equal(got, v.half().to(v.dtype)), k

    config = GestureModelConfig.preset("tiny")
    assert config.vae.low_frequency_path and config.vae.detail_path  # the DCT bases and column index below
    gesture = GestureModel(config)
    state = {k: v for k, v in gesture.state_dict().items() if k != "latent_residual_tril"}
    gesture.latent_residual_tril.fill_(1.0)
    from safetensors.torch import save_file

    save_model(tmp_path / "g", "gesture", gesture, gesture.config)
    save_file({k: v.contiguous() for k, v in state.items()}, str(tmp_path / "g" / "model.safetensors"),
              metadata={"format": "pt"})
    meta = json.loads((tmp_path / "g" / "model.json").read_text())
    meta["weights_sha256"] = file_sha256(tmp_path / "g" / "model.safetensors")
    meta["checksum_sha256"] = content_checksum(meta)
    (tmp_path / "g" / "model.json").write_text(json.dumps(meta))
    g = load_model(tmp_path / "g", "gesture").model
    assert not g.latent_residual_tril.any() and not g.latent_residual_tril.is_meta  # not in the file: zeros
    assert all(torch.equal(v, g.state_dict()[k]) for k, v in state.items())
    computed = {k: v for k, v in gesture.named_buffers() if k not in gesture.state_dict()}
    assert {"prior.dct_basis", "prior.detail_basis", "prior.detail_index"} <= set(computed)
    assert all(torch.equal(dict(g.named_buffers())[k], v) for k, v in computed.items())


def test_a_model_that_computes_a_buffer_on_the_default_device_is_named(tmp_path, monkeypatch):
    from emogesture import checkpoints
    from emogesture.errors import EmogestureError

    model = _model()
    save_model(tmp_path / "x", "extractor", model, model.config)

    def build(config):
        m = MotionFeatureExtractor(config)
        m.register_buffer("table", torch.arange(3.0), persistent=False)  # on the meta device while loading
        return m

    checkpoints._builtin_kinds()
    monkeypatch.setitem(checkpoints._KINDS, "extractor", checkpoints.ModelKind(ExtractorConfig, build))
    with pytest.raises(EmogestureError, match="MotionFeatureExtractor built table from its config on the meta device"):
        load_model(tmp_path / "x", "extractor")


def test_weights_replaced_while_they_load_are_refused(tmp_path, monkeypatch):
    import emogesture.checkpoints as checkpoints

    model = _model()
    save_model(tmp_path / "x", "extractor", model, model.config)
    stamps = iter(range(100))  # every look at the file sees another one (a save renamed over it)
    monkeypatch.setattr(checkpoints, "_file_stamp", lambda path: next(stamps))
    with pytest.raises(InputFileError, match=r"model.safetensors: changed while it was being loaded"):
        load_model(tmp_path / "x", "extractor")


def test_errors_name_the_file(tmp_path):
    model = _model()
    with pytest.raises(InputFileError, match="model.json: model file not found"):
        load_model(tmp_path / "none", "extractor")
    save_model(tmp_path / "run", "extractor", model, model.config)
    with pytest.raises(InputFileError, match="holds a 'extractor' model, but a 'speech' model is needed"):
        load_model(tmp_path / "run", "speech")
    with pytest.raises(OutputExistsError, match="--overwrite"):
        save_model(tmp_path / "run", "extractor", model, model.config, overwrite=False)
    meta_path = tmp_path / "run" / "model.json"
    meta = json.loads(meta_path.read_text())
    meta["format_version"] = 99
    meta_path.write_text(json.dumps(meta))
    with pytest.raises(InputFileError, match="format version 99"):
        read_meta(tmp_path / "run")
    # weights from another save
    save_model(tmp_path / "run", "extractor", model, model.config)
    save_model(tmp_path / "other", "extractor", _model(1), model.config)
    (tmp_path / "run" / "model.safetensors").write_bytes((tmp_path / "other" / "model.safetensors").read_bytes())
    with pytest.raises(InputFileError, match="checksum"):
        load_model(tmp_path / "run", "extractor")
    (tmp_path / "x.json").write_text("{not json")
    with pytest.raises(InputFileError, match="x.json"):
        load_model(tmp_path / "x.json", "extractor")


def _reseal(meta_path, change):
    """Edit a model JSON and give it a matching content checksum (a file from a buggy writer)."""
    meta = json.loads(meta_path.read_text())
    change(meta)
    meta["checksum_sha256"] = content_checksum(meta)
    meta_path.write_text(json.dumps(meta))


def test_an_edited_config_that_keeps_the_shapes_is_refused(tmp_path):
    model = _model()
    meta_path = save_model(tmp_path / "run", "extractor", model, model.config, {"motion_mean": [0.0]})
    meta = json.loads(meta_path.read_text())
    meta["config"]["dropout"] = 0.5  # same shapes, another model
    meta_path.write_text(json.dumps(meta))
    with pytest.raises(InputFileError, match=r"model.json: its content does not match its checksum"):
        load_model(tmp_path / "run", "extractor")
    meta = json.loads(meta_path.read_text())
    meta["config"]["dropout"] = model.config.dropout
    meta["extra"]["motion_mean"] = [1.0]  # the stored statistics are covered too
    meta_path.write_text(json.dumps(meta))
    with pytest.raises(InputFileError, match="checksum"):
        load_model(tmp_path / "run", "extractor")


def test_every_broken_file_is_a_one_line_error_naming_it(tmp_path):
    model = _model()
    run = tmp_path / "run"
    meta_path = save_model(run, "extractor", model, model.config)
    weights = run / "model.safetensors"
    good_meta, good_weights = meta_path.read_text(), weights.read_bytes()

    def expect(pattern, name="model.json"):
        with pytest.raises(InputFileError) as err:
            load_model(run, "extractor")
        message = str(err.value)
        assert "\n" not in message and name in message and re.search(pattern, message), message
        meta_path.write_text(good_meta)
        weights.write_bytes(good_weights)

    _reseal(meta_path, lambda m: m.pop("config"))
    expect("no valid 'config'")
    _reseal(meta_path, lambda m: m["config"].update(ff_dim=-64))
    expect("invalid stored config")
    _reseal(meta_path, lambda m: m["config"].update(depth=m["config"]["depth"] + 1))
    expect("do not fit the stored config", "model.safetensors")
    other = MotionFeatureExtractor(ExtractorConfig(**{**json.loads(good_meta)["config"],
                                                      "ff_dim": 2 * model.config.ff_dim}))
    save_model(tmp_path / "wide", "extractor", other, other.config)
    weights.write_bytes((tmp_path / "wide" / "model.safetensors").read_bytes())
    _reseal(meta_path, lambda m: m.update(weights_sha256=file_sha256(weights)))
    expect("size mismatch|do not fit", "model.safetensors")
    weights.write_bytes(b"\x00" * 64)
    _reseal(meta_path, lambda m: m.update(weights_sha256=file_sha256(weights)))
    expect("corrupt weights file", "model.safetensors")
    meta_path.write_bytes(b"\xff\xfe\x00garbage")
    expect("not a readable model description")
    weights.unlink()
    weights.mkdir()  # unreadable (a folder where the weights should be)
    with pytest.raises(InputFileError, match=r"model.safetensors: cannot read the weights"):
        load_model(run, "extractor")


_KILLED_SAVE = """
import os, sys, torch
from emogesture import checkpoints
from emogesture.models.extractor import ExtractorConfig, MotionFeatureExtractor
when = sys.argv[2]
real_replace = os.replace
def replace(src, dst):
    if when == "before_json" and str(dst).endswith("model.json"):
        os._exit(9)
    real_replace(src, dst)
os.replace = replace
if when == "after_json":
    checkpoints._commit_pending = lambda *a: os._exit(9)
torch.manual_seed(1)
model = MotionFeatureExtractor(ExtractorConfig.preset("tiny"))
checkpoints.save_model(sys.argv[1], "extractor", model, model.config, {"step": 2})
"""


@pytest.mark.parametrize("when", ["before_json", "after_json"])
def test_a_save_killed_between_its_two_writes_leaves_one_whole_model(tmp_path, when):
    model = _model(0)
    save_model(tmp_path / "run", "extractor", model, model.config, {"step": 1})
    proc = subprocess.run([sys.executable, "-c", _KILLED_SAVE, str(tmp_path / "run"), when])
    assert proc.returncode == 9
    loaded = load_model(tmp_path / "run", "extractor")
    want = 1 if when == "before_json" else 2
    assert loaded.metadata.step == want
    reference = model if want == 1 else _model(1)
    for k, v in reference.state_dict().items():
        assert torch.equal(loaded.model.state_dict()[k], v), k
    # the next save cleans up whatever the killed one left
    save_model(tmp_path / "run", "extractor", model, model.config, {"step": 3})
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["model.json", "model.safetensors"]
    assert load_model(tmp_path / "run", "extractor").metadata.step == 3


def test_a_device_problem_is_not_read_as_a_bad_weights_file(tmp_path):
    """Weights are read on the CPU and the model moved afterwards, so the device asked for never reaches
    the file reader (which called a device it could not use a "corrupt weights file")."""

    from emogesture.checkpoints import load_model, save_model
    from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig

    cfg = SpeechModelConfig.preset("tiny", num_speakers=2)
    save_model(tmp_path / "m", "speech", SpeechDisentangler(cfg), cfg, {})
    loaded = load_model(tmp_path / "m", "speech", device="meta")
    assert {p.device.type for p in loaded.model.parameters()} == {"meta"}


def test_a_model_too_large_for_the_device_is_a_one_line_error(tmp_path, monkeypatch):
    import torch

    from emogesture.checkpoints import load_model, save_model
    from emogesture.errors import EmogestureError
    from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig

    cfg = SpeechModelConfig.preset("tiny", num_speakers=2)
    save_model(tmp_path / "m", "speech", SpeechDisentangler(cfg), cfg, {})

    def out_of_memory(self, *args, **kwargs):
        raise torch.cuda.OutOfMemoryError("CUDA out of memory. Tried to allocate 20.00 MiB")

    monkeypatch.setattr(torch.nn.Module, "to", out_of_memory)
    with pytest.raises(EmogestureError, match=r"model\.json: the model does not fit in the memory of cuda:1$"):
        load_model(tmp_path / "m", "speech", device="cuda:1")


def test_metadata_is_typed_keeps_what_it_does_not_know_and_names_what_is_missing(tmp_path):
    model = _model()
    save_model(tmp_path / "run", "extractor", model, model.config,
               ExtractorMetadata(step=7, motion_mean=[0, 1], other={"from_a_newer_version": {"a": 1}}))
    loaded = load_model(tmp_path / "run", "extractor")
    assert isinstance(loaded.metadata, ExtractorMetadata) and loaded.metadata.step == 7
    assert loaded.metadata.motion_mean == [0.0, 1.0] and all(isinstance(v, float) for v in loaded.metadata.motion_mean)
    assert loaded.metadata.other == {"from_a_newer_version": {"a": 1}}
    save_model(tmp_path / "copy", "extractor", loaded.model, loaded.config, loaded.metadata)
    assert json.loads((tmp_path / "copy" / "model.json").read_text())["extra"]["from_a_newer_version"] == {"a": 1}
    with pytest.raises(ConfigError, match="holds no 'motion_std'"):
        loaded.metadata.require("motion_std", loaded.path)
    with pytest.raises(ConfigError, match="GestureMetadata given for a extractor model"):
        save_model(tmp_path / "bad", "extractor", model, model.config, GestureMetadata(step=1))
    stored = json.loads((tmp_path / "run" / "model.json").read_text())
    stored["extra"]["step"] = "many"
    stored["checksum_sha256"] = content_checksum(stored)
    (tmp_path / "run" / "model.json").write_text(json.dumps(stored))
    with pytest.raises(InputFileError, match=r"model.json: invalid stored data \(extra.step: 'many' fits none of int"):
        load_model(tmp_path / "run", "extractor")
