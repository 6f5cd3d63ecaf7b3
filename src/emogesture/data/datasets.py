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

    @property
    def window_samples(self) -> int:
        """Waveform samples behind one fbank window."""
        c = self.fbank_config
        return (self.frames - 1) * c.frame_shift + c.frame_length

    def window_fbank(self, wave: np.ndarray) -> np.ndarray:
        """A window's waveform ``[window_samples]`` -> its fbank ``[frames, n_mels]`` float32, as the cache's."""
        fb = normalise_fbank(normalise_recording(kaldi_fbank(wave, self.fbank_config), self.recording_norm),
                             self.mean, self.std)
        return fbank_window(fb, 0, self.frames).numpy()

    def __call__(self, j: int, rng: np.random.Generator) -> np.ndarray:
        """Window ``j``'s fbank ``[frames, n_mels]`` float32, its waveform augmented with draws from ``rng``."""
        c = self.fbank_config
        first = int(round(float(self.windows.start_s[j]) * c.sample_rate / c.frame_shift))  # the cache's first frame
        start = first * c.frame_shift
        wave = self.waves[self.windows.takes[j]][start: start + self.window_samples]
        wave, _ = augment_waveform(wave, rng, self.config)
        return self.window_fbank(wave)


#: The key that sets an augmented variant's draws apart from the quadruples' (``[seed, epoch, item]``).
VARIANT_STREAM = 0xA6


def _one_thread() -> None:
    """A forked maker of variants computes its filterbanks on one thread, as a data worker does (a forked
    process's copy of the parent's thread pool would hang)."""
    torch.set_num_threads(1)


def _variant_fbank(job: tuple[int, int, int]) -> np.ndarray:
    """Window ``j``'s augmented variant ``v`` (run seed ``seed``), in a process forked from the bank's maker."""
    j, v, seed = job
    return _BANK_AUGMENTER(j, np.random.default_rng([seed, VARIANT_STREAM, j, v])).astype(np.float16)


_BANK_AUGMENTER: WaveWindowAugmenter | None = None


class AugmentedWindowBank:
    """Each window of an augmenter's split heard through ``variants`` draws of the augmented conditions, made
    once, before training, in ``processes`` forked processes (None: one per core; with ``progress``, a bar on
    a terminal). Called like the augmenter (``bank(j, rng)``), it gives one of window ``j``'s variants, chosen
    by ``rng``.

    Variant ``v`` of window ``j`` is drawn from ``default_rng([seed, VARIANT_STREAM, j, v])``: the same bank
    whatever the number of processes. The variants are kept in memory as float16 fbank windows
    (``[N, variants, frames, n_mels]``: about 2.5 GB for 1200 windows and 8 variants) and shared with the data
    workers. On a CPU, the waveform augmentation is most of a training step's work when it is drawn afresh;
    a bank does it once per variant instead of once per use.
    """

    def __init__(self, augmenter: WaveWindowAugmenter, variants: int, seed: int, processes: int | None = None,
                 progress: bool = True) -> None:
        import multiprocessing
        import os

        from tqdm import tqdm

        if variants < 1:
            raise ValueError(f"variants {variants}: must be at least 1")
        global _BANK_AUGMENTER
        n, frames, bins = augmenter.windows.fbank.shape
        self.variants = variants
        self.fbank = np.empty((n, variants, frames, bins), np.float16)
        jobs = [(j, v, seed) for j in range(n) for v in range(variants)]
        processes = processes or len(os.sched_getaffinity(0))
        _BANK_AUGMENTER = augmenter
        try:
            with tqdm(total=len(jobs), desc="augmented windows", unit="window",
                      disable=None if progress else True) as bar:
                if processes == 1:
                    self._fill(jobs, map(_variant_fbank, jobs), bar)
                else:
                    with multiprocessing.get_context("fork").Pool(processes, _one_thread) as pool:
                        self._fill(jobs, pool.imap(_variant_fbank, jobs, chunksize=8), bar)
        finally:
            _BANK_AUGMENTER = None

    def _fill(self, jobs: list[tuple[int, int, int]], made, bar) -> None:
        for (j, v, _), fbank in zip(jobs, made):
            self.fbank[j, v] = fbank
            bar.update()

    def __call__(self, j: int, rng: np.random.Generator) -> np.ndarray:
        """One of window ``j``'s variants ``[frames, n_mels]`` float32, drawn from ``rng``."""
        return np.asarray(self.fbank[j, int(rng.integers(self.variants))], np.float32)


class SpeechQuadrupleDataset(Dataset):
    """Seeded quadruples ``(c1 s1, c2 s1, c1 s2, c2 s2)`` of fbank windows (docs/design.md, 'Speech
    disentanglement model').

    Item ``i`` of epoch ``e`` is drawn from ``default_rng([seed, e, i])``: reproducible, and
    independent of worker count or order. Each item is a dict with ``fbank [4, 1024, n_mels]``
    float32, ``emotion`` (int) and ``speaker [4]`` (class indices into ``speakers``). With an
    ``augmenter`` (drawn afresh, or one of an :class:`AugmentedWindowBank`'s variants), each window is also
    heard through augmented conditions with probability ``augment_share`` (the same generator decides):
    ``inputs [4, 1024, n_mels]``, ``fbank`` staying the
    clean windows (the reconstruction target). With ``level_jitter_db`` > 0, every window is also heard at a
    level moved by a gain drawn from ±``level_jitter_db`` dB (``fbank_std``: the windows'
    normalisation, which scales the shift of each bin).
    """

    def __init__(self, windows: SplitWindows, speakers: list[int], length: int, seed: int = 0,
                 augmenter: WaveWindowAugmenter | AugmentedWindowBank | None = None,
                 augment_share: float = 0.0, level_jitter_db: float = 0.0,
                 fbank_std: np.ndarray | None = None) -> None:
        if not 0.0 <= augment_share <= 1.0:
            raise ValueError(f"augment_share {augment_share} is not in [0, 1]")
        if level_jitter_db < 0 or (level_jitter_db > 0 and fbank_std is None):
            raise ValueError("level_jitter_db must be >= 0 and needs the windows' fbank_std")
        self.augmenter, self.augment_share = augmenter, augment_share
        # a gain of d dB moves every log-mel bin (natural log of power) by d ln(10) / 10, and the normalised
        # window (normalise_fbank: divided by twice the std) by half that over the std
        self.level_jitter_db = level_jitter_db
        self.level_step = (np.log(10) / 10 / (2 * np.asarray(fbank_std, np.float32))).astype(np.float32) \
            if level_jitter_db > 0 else None
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
        if self.augmenter is not None or self.level_step is not None:
            heard = fbank.copy()
            if self.augmenter is not None:
                for k, j in enumerate(q.indices):
                    if rng.random() < self.augment_share:
                        heard[k] = self.augmenter(j, rng)
            if self.level_step is not None:  # every window heard at its own level (drawn after the above)
                gains = rng.uniform(-self.level_jitter_db, self.level_jitter_db, len(q.indices)).astype(np.float32)
                heard += gains[:, None, None] * self.level_step
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
