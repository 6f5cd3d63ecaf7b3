"""Torch datasets over a prepared windows cache."""

from __future__ import annotations

import numpy as np
import torch
from torch.utils.data import Dataset

from emogesture.data.cache import SplitWindows
from emogesture.data.quadruples import QuadrupleIndex


class SpeechQuadrupleDataset(Dataset):
    """Seeded quadruples ``(c1 s1, c2 s1, c1 s2, c2 s2)`` of fbank windows (SPEC §2).

    Item ``i`` of epoch ``e`` is drawn from ``default_rng([seed, e, i])``: reproducible, and
    independent of worker count or order. Each item is a dict with ``fbank [4, 1024, n_mels]``
    float32, ``emotion`` (int) and ``speaker [4]`` (class indices into ``speakers``).
    """

    def __init__(self, windows: SplitWindows, speakers: list[int], length: int, seed: int = 0) -> None:
        self.windows = windows
        self.index = QuadrupleIndex(windows)
        self.speaker_class = {s: i for i, s in enumerate(speakers)}
        self.length = length
        self.seed = seed
        self.epoch = 0

    def __len__(self) -> int:
        return self.length

    def __getitem__(self, i: int) -> dict:
        q = self.index.draw(np.random.default_rng([self.seed, self.epoch, int(i)]))
        fbank = np.stack([np.asarray(self.windows.fbank[j], np.float32) for j in q.indices])
        return {
            "fbank": torch.from_numpy(fbank),
            "emotion": torch.tensor(q.emotion),
            "speaker": torch.tensor([self.speaker_class[s] for s in q.speakers]),
        }


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
