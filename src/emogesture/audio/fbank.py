"""Kaldi-compatible log-mel filterbank features in torch (docs/design.md, 'Audio front end').

Kaldi's ``compute-fbank-feats`` algorithm, step for step (``feat/feature-window.cc``,
``feat/feature-fbank.cc``, ``feat/mel-computations.cc``):

1. frames of ``frame_length_ms`` every ``frame_shift_ms`` (``snip_edges``: only whole frames, the first
   starting at sample 0; otherwise ``round(N / shift)`` frames centred on ``shift * (t + 1/2)`` with the
   signal reflected at the ends);
2. optional Gaussian dither;
3. per-frame DC removal (subtract the frame mean);
4. (raw log-energy, if ``use_energy``);
5. pre-emphasis ``y[i] = x[i] - k x[i-1]`` with ``y[0] = x[0] - k x[0]``;
6. the window function;
7. zero-padding to the next power of two and the power spectrum ``|FFT|^2``;
8. HTK-mel triangular filters built in the mel domain (:func:`emogesture.audio.mel.kaldi_mel_banks`);
9. ``log(max(energy, float32 epsilon))``.

Scale: the waveform is used in whatever scale the caller passes — it is *not* rescaled to the int16 range.
AST and the AMUSE release feed float waveforms in ``[-1, 1]`` (torchaudio's ``kaldi.fbank`` on a
``torchaudio.load`` result), and the normalisation statistics ``FBANK_MEAN`` / ``FBANK_STD`` were computed on
that scale; an int16-scaled input shifts every log energy by ``2 ln 32768 ≈ 20.8``.

Windows: ``'hamming'`` (the paper), ``'hann'`` (Kaldi's symmetric ``hanning``, ``0.5 - 0.5 cos(2πn/(N-1))``,
what the authors' release used through torchaudio), ``'povey'``, ``'rectangular'``, ``'blackman'``.
Note ``kaldi_native_fbank``'s ``'hann'`` is the *periodic* variant; its ``'hanning'`` is ours.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import torch

from emogesture.audio.io import TARGET_SAMPLE_RATE
from emogesture.audio.mel import kaldi_mel_banks
from emogesture.audio.stft import as_float_tensor, frame_signal, power_spectrum
from emogesture.errors import ConfigError

__all__ = [
    "FLOAT32_EPS",
    "WINDOW_TYPES",
    "FbankConfig",
    "kaldi_fbank",
    "kaldi_window",
    "num_fbank_frames",
]

FLOAT32_EPS: float = float(np.finfo(np.float32).eps)
WINDOW_TYPES: tuple[str, ...] = ("hamming", "hann", "hanning", "povey", "rectangular", "blackman")


@dataclass(frozen=True)
class FbankConfig:
    """Kaldi fbank options (defaults as in docs/design.md, 'Audio front end': 128 bins, 25 ms / 10 ms, dither 0,
    Hamming, 20 Hz..Nyquist).

    ``high_freq <= 0`` is an offset from Nyquist (0 = Nyquist), as in Kaldi. With ``use_energy`` the log
    energy becomes column 0 (Kaldi's order without ``--htk-compat``) and the output has ``num_mel_bins + 1``
    columns.
    """

    sample_rate: int = TARGET_SAMPLE_RATE
    num_mel_bins: int = 128
    frame_length_ms: float = 25.0
    frame_shift_ms: float = 10.0
    dither: float = 0.0
    preemphasis: float = 0.97
    remove_dc_offset: bool = True
    window: str = "hamming"
    blackman_coeff: float = 0.42
    low_freq: float = 20.0
    high_freq: float = 0.0
    use_energy: bool = False
    raw_energy: bool = True
    energy_floor: float = 0.0
    snip_edges: bool = True
    round_to_power_of_two: bool = True
    log_floor: float = field(default=FLOAT32_EPS)

    def __post_init__(self) -> None:
        if self.window not in WINDOW_TYPES:
            raise ConfigError(f"fbank window must be one of {', '.join(WINDOW_TYPES)}; got {self.window!r}")
        if self.sample_rate <= 0:
            raise ConfigError(f"fbank sample_rate must be positive, got {self.sample_rate}")
        if self.num_mel_bins < 1:
            raise ConfigError(f"fbank num_mel_bins must be >= 1, got {self.num_mel_bins}")
        if self.frame_length < 2 or self.frame_shift < 1:
            raise ConfigError(
                f"fbank frame_length_ms={self.frame_length_ms} / frame_shift_ms={self.frame_shift_ms} give "
                f"{self.frame_length} / {self.frame_shift} samples at {self.sample_rate} Hz"
            )
        if not 0.0 <= self.preemphasis <= 1.0:
            raise ConfigError(f"fbank preemphasis must be in [0, 1], got {self.preemphasis}")
        if self.dither < 0.0:
            raise ConfigError(f"fbank dither must be >= 0, got {self.dither}")
        if not self.log_floor > 0.0:
            raise ConfigError(f"fbank log_floor must be > 0, got {self.log_floor}")
        # Validates the frequency range (raises ConfigError).
        kaldi_mel_banks(self.num_mel_bins, self.padded_window_size, float(self.sample_rate),
                        float(self.low_freq), float(self.high_freq))

    @property
    def frame_length(self) -> int:
        """Window length in samples (Kaldi truncates ``sample_rate * ms / 1000``)."""
        return int(self.sample_rate * 0.001 * self.frame_length_ms)

    @property
    def frame_shift(self) -> int:
        """Frame shift in samples."""
        return int(self.sample_rate * 0.001 * self.frame_shift_ms)

    @property
    def padded_window_size(self) -> int:
        """FFT size: the frame length, rounded up to a power of two if ``round_to_power_of_two``."""
        n = self.frame_length
        return 1 << (n - 1).bit_length() if self.round_to_power_of_two else n

    @property
    def num_features(self) -> int:
        """Columns of the output (``num_mel_bins``, +1 with ``use_energy``)."""
        return self.num_mel_bins + int(self.use_energy)

    def mel_banks(self) -> np.ndarray:
        """The ``[num_mel_bins, padded_window_size // 2 + 1]`` filter matrix (read-only, cached)."""
        return kaldi_mel_banks(self.num_mel_bins, self.padded_window_size, float(self.sample_rate),
                               float(self.low_freq), float(self.high_freq))

    def empty_bins(self) -> list[int]:
        """Indices of mel filters that cover no FFT bin; their output is always ``log(log_floor)``."""
        return [int(i) for i in np.flatnonzero(~(self.mel_banks() > 0).any(axis=1))]


def num_fbank_frames(num_samples: int, config: FbankConfig | None = None) -> int:
    """How many frames :func:`kaldi_fbank` gives for ``num_samples`` samples (998 for 10 s at the defaults)."""
    cfg = config or FbankConfig()
    if cfg.snip_edges:
        return 0 if num_samples < cfg.frame_length else 1 + (num_samples - cfg.frame_length) // cfg.frame_shift
    return (num_samples + cfg.frame_shift // 2) // cfg.frame_shift


def kaldi_window(window: str, length: int, blackman_coeff: float = 0.42,
                 dtype: torch.dtype = torch.float64, device: torch.device | str | None = None) -> torch.Tensor:
    """Kaldi's ``FeatureWindowFunction`` (symmetric: ``a = 2π / (length - 1)``)."""
    n = torch.arange(length, dtype=torch.float64)
    a = 2.0 * math.pi / (length - 1)
    if window in ("hann", "hanning"):
        w = 0.5 - 0.5 * torch.cos(a * n)
    elif window == "hamming":
        w = 0.54 - 0.46 * torch.cos(a * n)
    elif window == "povey":
        w = (0.5 - 0.5 * torch.cos(a * n)).pow(0.85)
    elif window == "rectangular":
        w = torch.ones(length, dtype=torch.float64)
    elif window == "blackman":
        w = blackman_coeff - 0.5 * torch.cos(a * n) + (0.5 - blackman_coeff) * torch.cos(2.0 * a * n)
    else:
        raise ConfigError(f"unknown window type {window!r}; expected one of {', '.join(WINDOW_TYPES)}")
    return w.to(dtype=dtype, device=device)


#: Frames per chunk of :func:`kaldi_fbank` (5.12 s at the 10-ms shift). 10 min of audio took 0.84 s
#: computed whole and 0.19–0.26 s in chunks of 512 (2 cores; 1024: 0.21–0.24 s, 4096: 0.38–0.55 s).
FBANK_CHUNK_FRAMES = 512


def _extract_frames(x: torch.Tensor, cfg: FbankConfig) -> torch.Tensor:
    length, shift = cfg.frame_length, cfg.frame_shift
    if cfg.snip_edges:
        return frame_signal(x, length, shift)
    n = x.shape[-1]
    num_frames = num_fbank_frames(n, cfg)
    if num_frames == 0 or n == 0:
        return x.new_zeros((*x.shape[:-1], 0, length))
    starts = torch.arange(num_frames, device=x.device) * shift + shift // 2 - length // 2
    idx = starts[:, None] + torch.arange(length, device=x.device)[None, :]
    # Kaldi's reflection: s < 0 -> -s - 1; s >= n -> 2n - 1 - s; repeated until in range.
    while bool(((idx < 0) | (idx >= n)).any()):
        idx = torch.where(idx < 0, -idx - 1, idx)
        idx = torch.where(idx >= n, 2 * n - 1 - idx, idx)
    return x[..., idx]


def _resolve_config(config: FbankConfig | None, overrides: dict) -> FbankConfig:
    cfg = config if config is not None else FbankConfig()
    if not overrides:
        return cfg
    names = {f.name for f in dataclasses.fields(FbankConfig)}
    unknown = sorted(set(overrides) - names)
    if unknown:
        raise ConfigError(f"unknown fbank option(s): {', '.join(unknown)}; known: {', '.join(sorted(names))}")
    return dataclasses.replace(cfg, **overrides)


def kaldi_fbank(
    waveform: np.ndarray | torch.Tensor,
    config: FbankConfig | None = None,
    *,
    generator: torch.Generator | None = None,
    **overrides,
) -> torch.Tensor:
    """Kaldi log-mel filterbank of ``waveform`` ``[N]`` (or ``[..., N]``) -> float32 ``[frames, bins]``.

    Args:
        waveform: mono samples at ``config.sample_rate``, numpy or torch, in the caller's scale (see the
            module docstring: AST/AMUSE use floats in ``[-1, 1]``; nothing is rescaled).
        config: options; ``None`` means :class:`FbankConfig` defaults.
        generator: random source for the dither (only used when ``dither > 0``).
        **overrides: individual :class:`FbankConfig` fields, e.g. ``num_mel_bins=80, window='hann'``.

    Returns:
        float32 tensor on the input's device, ``[..., num_frames, num_features]``; ``num_frames`` is
        :func:`num_fbank_frames` (0 rows when the input is shorter than one frame). Computation is float64
        on the CPU, float32 elsewhere.
    """
    cfg = _resolve_config(config, overrides)
    x = as_float_tensor(waveform)
    if x.ndim == 0:
        raise ValueError("waveform must have at least one dimension [N]")
    frames = _extract_frames(x, cfg)  # [..., F, L]
    noise = None
    if cfg.dither > 0.0:  # drawn for every frame at once: the same draws however the frames are chunked
        noise = torch.randn(frames.shape, generator=generator, dtype=frames.dtype).to(frames.device)
    window = kaldi_window(cfg.window, cfg.frame_length, cfg.blackman_coeff, frames.dtype, frames.device)
    banks = torch.tensor(np.array(cfg.mel_banks()), dtype=frames.dtype, device=frames.device).T
    n = frames.shape[-2]
    if n <= FBANK_CHUNK_FRAMES:
        return _fbank_of_frames(frames, noise, window, banks, cfg)
    # long audio in bounded chunks of frames: every frame is computed alone, so the result is the same,
    # and the float64 intermediates (about 8 kB per frame) stay in the caches instead of growing with the
    # audio (10 min: 60 000 frames, about 0.5 GB per whole-signal intermediate)
    return torch.cat([_fbank_of_frames(frames[..., i: i + FBANK_CHUNK_FRAMES, :],
                                       None if noise is None else noise[..., i: i + FBANK_CHUNK_FRAMES, :],
                                       window, banks, cfg)
                      for i in range(0, n, FBANK_CHUNK_FRAMES)], dim=-2)


def rolled_fbank(previous: torch.Tensor | None, waveform: np.ndarray | torch.Tensor, shift: int,
                 config: FbankConfig | None = None) -> torch.Tensor:
    """:func:`kaldi_fbank` of ``waveform [N]``, a buffer of fixed length that has moved on by ``shift`` samples
    since ``previous`` (its filterbank ``[frames, bins]`` then) was computed: the frames still inside the buffer
    are taken from ``previous`` and only the newest computed. Every frame is computed alone, so the result is
    the same as computing it whole, which it does where nothing can be reused (no ``previous``, a ``shift``
    that is not a whole number of frame shifts or leaves no frame in common, snip_edges off, dither). A live
    stream's window moves by a quarter of a second at each update: its 10-s filterbank then costs 25 frames,
    not 998."""
    cfg = config or FbankConfig()
    frames = num_fbank_frames(len(waveform), cfg)
    step = cfg.frame_shift
    s = shift // step
    reuse = (previous is not None and cfg.snip_edges and cfg.dither == 0.0 and shift % step == 0
             and 0 <= s < frames and previous.shape[0] == frames)
    if not reuse:
        return kaldi_fbank(waveform, cfg)
    if s == 0:
        return previous
    newest = kaldi_fbank(waveform[step * (frames - s): step * (frames - 1) + cfg.frame_length], cfg)
    return torch.cat([previous[s:], newest])


def _fbank_of_frames(frames: torch.Tensor, noise: torch.Tensor | None, window: torch.Tensor, banks: torch.Tensor,
                     cfg: FbankConfig) -> torch.Tensor:
    """Steps 2-9 of the module docstring for ``frames [..., F, L]`` -> float32 ``[..., F, bins]``."""
    if noise is not None:
        frames = frames + cfg.dither * noise
    if cfg.remove_dc_offset:
        frames = frames - frames.mean(dim=-1, keepdim=True)
    log_energy = None
    if cfg.use_energy and cfg.raw_energy:
        log_energy = frames.square().sum(dim=-1).clamp_min(FLOAT32_EPS).log()
    if cfg.preemphasis != 0.0:
        k = cfg.preemphasis
        frames = torch.cat([frames[..., :1] * (1.0 - k), frames[..., 1:] - k * frames[..., :-1]], dim=-1)
    frames = frames * window
    if cfg.use_energy and not cfg.raw_energy:
        log_energy = frames.square().sum(dim=-1).clamp_min(FLOAT32_EPS).log()
    power = power_spectrum(frames, cfg.padded_window_size)  # [..., F, n_fft/2 + 1]
    mel = (power @ banks).clamp_min(cfg.log_floor).log()
    if log_energy is not None:
        if cfg.energy_floor > 0.0:
            log_energy = log_energy.clamp_min(math.log(cfg.energy_floor))
        mel = torch.cat([log_energy.unsqueeze(-1), mel], dim=-1)
    return mel.to(torch.float32)
