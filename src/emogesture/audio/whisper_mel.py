"""Whisper's log-mel spectrogram (the input of its encoder): 16 kHz, 25-ms Hann windows every 10 ms, 80 Slaney
mel bins (:func:`emogesture.audio.mel.librosa_mel_banks`), log10 floored 8 decades below the loudest bin and
scaled as Whisper scales it (``(x + 4) / 4``)."""

from __future__ import annotations

import numpy as np
import torch

from emogesture.audio.mel import librosa_mel_banks

SAMPLE_RATE = 16_000
N_FFT, HOP, N_MELS = 400, 160, 80


def whisper_log_mel(waveform: np.ndarray) -> np.ndarray:
    """A 16 kHz waveform ``[N]`` -> log-mel ``[80, N // 160]`` float32, as Whisper's encoder hears it."""
    x = np.asarray(waveform, np.float64)
    if len(x) < N_FFT:
        x = np.pad(x, (0, N_FFT - len(x)))
    x = np.pad(x, (N_FFT // 2, N_FFT // 2), mode="reflect")
    frames = 1 + (len(x) - N_FFT) // HOP
    index = np.arange(N_FFT)[None] + HOP * np.arange(frames)[:, None]
    power = np.abs(np.fft.rfft(x[index] * np.hanning(N_FFT + 1)[:-1], axis=1)) ** 2
    # the product in torch, not numpy: numpy's BLAS threads keep spinning after it on the cores torch then needs,
    # and the encoder that hears this log-mel next ran five times as slowly (0.11 s a window against 0.02 s)
    banks = torch.tensor(librosa_mel_banks(SAMPLE_RATE, N_FFT, N_MELS), dtype=torch.float64)
    mel = (banks @ torch.from_numpy(np.ascontiguousarray(power[:-1].T))).numpy()
    log = np.log10(np.maximum(mel, 1e-10))
    return ((np.maximum(log, log.max() - 8.0) + 4.0) / 4.0).astype(np.float32)
