"""Torch datasets over a prepared windows cache."""

from __future__ import annotations

import numpy as np
import torch
from torch.utils.data import Dataset

from emogesture.audio import FbankConfig, fbank_window, kaldi_fbank, load_audio, normalise_fbank, normalise_recording
from emogesture.audio.wave_augment import WaveAugmentConfig, augment_waveform
from emogesture.config import from_dict
from emogesture.data.cache import SplitWindows, WindowsCache
from emogesture.data.quadruples import QuadrupleIndex


class WaveWindowAugmenter:
    """Training windows heard through the conditions of :mod:`emogesture.audio.wave_augment`.

    Holds the waveforms of the takes behind a split's windows (read once from the corpus the cache was
    prepared from) and turns window ``j`` into its fbank window again after augmenting the waveform:
    cut where the cache's window starts, augmented, filterbank, measured against itself as the cache's
    takes were (``recording_norm``; the window stands for its recording), normalised with the cache's statistics,
    as many frames as the cache's windows. Without augmentation (a config of all zeros) it gives the
    cache's own window back to float16 rounding (with ``recording_norm`` ``none``; otherwise the window is
    measured against itself, the take's window against the whole take).
    """

    def __init__(self, cache: WindowsCache, windows: SplitWindows, config: WaveAugmentConfig) -> None:
        from pathlib import Path

        config.validate()
        self.windows, self.config = windows, config
        prepared = cache.manifest["config"]
        self.fbank_config = from_dict(FbankConfig, prepared["fbank"]) if "fbank" in prepared else FbankConfig()
        self.recording_norm = prepared.get("recording_norm", "none")
        self.mean, self.std = float(cache.stats["fbank_mean"]), float(cache.stats["fbank_std"])
        self.frames = int(windows.fbank.shape[1])
        root = Path(cache.manifest["root"])
        self.waves = {take: load_audio(root / "wave16k" / f"{take}.wav")[0] for take in dict.fromkeys(windows.takes)}

    def __call__(self, j: int, rng: np.random.Generator) -> np.ndarray:
        """Window ``j``'s fbank ``[frames, n_mels]`` float32, its waveform augmented with draws from ``rng``."""
        c = self.fbank_config
        first = int(round(float(self.windows.start_s[j]) * c.sample_rate / c.frame_shift))  # the cache's first frame
        start = first * c.frame_shift
        wave = self.waves[self.windows.takes[j]][start: start + (self.frames - 1) * c.frame_shift + c.frame_length]
        wave, _ = augment_waveform(wave, rng, self.config)
        fb = normalise_fbank(normalise_recording(kaldi_fbank(wave, c), self.recording_norm), self.mean, self.std)
        return fbank_window(fb, 0, self.frames).numpy()


class SpeechQuadrupleDataset(Dataset):
    """Seeded quadruples ``(c1 s1, c2 s1, c1 s2, c2 s2)`` of fbank windows (docs/design.md, 'Speech
    disentanglement model').

    Item ``i`` of epoch ``e`` is drawn from ``default_rng([seed, e, i])``: reproducible, and
    independent of worker count or order. Each item is a dict with ``fbank [4, 1024, n_mels]``
    float32, ``emotion`` (int) and ``speaker [4]`` (class indices into ``speakers``). With an
    ``augmenter``, each window is also heard through augmented conditions with probability
    ``augment_share`` (the same generator decides): ``inputs [4, 1024, n_mels]``, ``fbank`` staying the
    clean windows (the reconstruction target).
    """

    def __init__(self, windows: SplitWindows, speakers: list[int], length: int, seed: int = 0,
                 augmenter: WaveWindowAugmenter | None = None, augment_share: float = 0.0) -> None:
        if not 0.0 <= augment_share <= 1.0:
            raise ValueError(f"augment_share {augment_share} is not in [0, 1]")
        self.augmenter, self.augment_share = augmenter, augment_share
        self.windows = windows
        self.index = QuadrupleIndex(windows)
        self.speaker_class = {s: i for i, s in enumerate(speakers)}
        self.length = length
        self.seed = seed
        self.epoch = 0

    def __len__(self) -> int:
        return self.length

    def __getitem__(self, i: int) -> dict:
        rng = np.random.default_rng([self.seed, self.epoch, int(i)])
        q = self.index.draw(rng)
        fbank = np.stack([np.asarray(self.windows.fbank[j], np.float32) for j in q.indices])
        item = {
            "fbank": torch.from_numpy(fbank),
            "emotion": torch.tensor(q.emotion),
            "speaker": torch.tensor([self.speaker_class[s] for s in q.speakers]),
        }
        if self.augmenter is not None:
            heard = fbank.copy()
            for k, j in enumerate(q.indices):
                if rng.random() < self.augment_share:
                    heard[k] = self.augmenter(j, rng)
            item["inputs"] = torch.from_numpy(heard)
        return item


class WindowDataset(Dataset):
    """Single windows: ``fbank [1024, n_mels]``, ``motion [300, D]`` (raw), labels and the index."""

    def __init__(self, windows: SplitWindows, with_fbank: bool = True, with_motion: bool = True) -> None:
        self.windows = windows
        self.with_fbank = with_fbank
        self.with_motion = with_motion

    def __len__(self) -> int:
        return len(self.windows)

    def __getitem__(self, i: int) -> dict:
        w = self.windows
        item = {"index": torch.tensor(i), "emotion": torch.tensor(int(w.emotion[i])),
                "speaker_id": torch.tensor(int(w.speaker_id[i]))}
        if self.with_fbank:
            item["fbank"] = torch.from_numpy(np.asarray(w.fbank[i], np.float32))
        if self.with_motion:
            item["motion"] = torch.from_numpy(np.asarray(w.motion[i], np.float32))
        return item
