"""Model files: round trip, atomic writes, and one-line errors for the wrong file."""

import json

import pytest
import torch

from emogesture.checkpoints import load_model, read_meta, save_model
from emogesture.errors import InputFileError, OutputExistsError
from emogesture.models.extractor import ExtractorConfig, MotionFeatureExtractor


def _model(seed=0):
    torch.manual_seed(seed)
    return MotionFeatureExtractor(ExtractorConfig.preset("tiny"))


def test_round_trip_gives_the_same_outputs(tmp_path):
    model = _model().eval()
    save_model(tmp_path / "run", "extractor", model, model.config, {"motion_mean": [0.0, 1.0]})
    loaded = load_model(tmp_path / "run", "extractor")
    assert loaded.config == model.config and loaded.extra == {"motion_mean": [0.0, 1.0]}
    x = torch.randn(2, 300, 282, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        a, b = model(x), loaded.model(x)
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["model.json", "model.safetensors"]


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
