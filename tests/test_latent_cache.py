"""The speech-latent cache of a split follows the windows' content, not only the preparation settings."""

import numpy as np
import soundfile as sf
import torch

from emogesture.checkpoints import save_model
from emogesture.data.cache import open_cache
from emogesture.data.prepare import prepare
from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig
from emogesture.eval.split_latents import encode_split
from emogesture.pipeline.speech import SpeechLatentEncoder
from emogesture.train.speech import speech_model_metadata

from helpers import make_root


def test_changed_take_gives_fresh_latents(tmp_path):
    names = make_root(tmp_path / "root")
    prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    cache = open_cache(tmp_path / "cache")
    torch.manual_seed(0)
    cfg = SpeechModelConfig.preset("tiny", num_speakers=2)
    save_model(tmp_path / "speech", "speech", SpeechDisentangler(cfg), cfg,
               speech_model_metadata(cache, [1, 2], 0, ["train"]))
    before = encode_split(SpeechLatentEncoder.from_run(tmp_path / "speech"), cache, "test")
    # cached beside the windows, never beside the model (the bundled model lives inside the package)
    assert len(list((tmp_path / "cache" / "latents").glob("*.npz"))) == 1 and not (tmp_path / "speech" / "latents").exists()

    # the same settings, one test take's speech replaced (as after `corpus --overwrite`)
    take = next(n for n in names if n.endswith("_2_2"))
    wave, sr = sf.read(tmp_path / "root" / "wave16k" / f"{take}.wav")
    t = np.arange(len(wave)) / sr
    sf.write(tmp_path / "root" / "wave16k" / f"{take}.wav", (0.3 * np.sin(2 * np.pi * 410 * t)).astype(np.float32), sr)
    prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    cache = open_cache(tmp_path / "cache")
    encoder = SpeechLatentEncoder.from_run(tmp_path / "speech")
    after = encode_split(encoder, cache, "test")
    split = cache.split("test")
    fresh = encoder.encode_windows(split.fbank, renormalise=(cache.stats["fbank_mean"], cache.stats["fbank_std"]))
    assert np.array_equal(after.emotion, fresh.emotion)
    assert not np.allclose(after.emotion, before.emotion)
    changed = np.asarray(split.takes) == take
    assert np.allclose(after.emotion[~changed], before.emotion[~changed], atol=1e-5)
