"""The speech's timing stream: loudness and onset strength of the fbank at the motion's frame rate.

A gesture model that hears timing (the tiny preset's decoder does) reads, per 1/30-s motion frame of a 10-s
window, two numbers of the normalised log-mel filterbank that window was cut from (:func:`emogesture.audio.fbank_windows`):

- ``loudness``: the mean over mel bands;
- ``onset_strength``: the half-wave rectified frame-to-frame increase, mean over mel bands (spectral
  flux: syllable onsets and stressed syllables stand out).

Each is averaged over the fbank frames a motion frame covers (100 fbank frames per second, so 10/3 per
motion frame) and standardised over the window's frames, so the stream carries *when* the speech
moves, not how loud or which speaker or emotion: a silent window gives zeros.

A window that runs past the end of its audio (the last window of a recording, aligned to end with it,
lacks the fbank's last two frames; a recording shorter than a window lacks more) repeats its last real
frame there when its ``lengths`` are given: the zeros a window is padded with would read as a step in
loudness and an onset where the speech has ended, which training windows, always cut inside their take,
never show.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from emogesture.audio.windows import FBANK_FRAMES_PER_SECOND

TIMING_FEATURES = ("loudness", "onset_strength")


@torch.no_grad()
def timing_stream(fbank: np.ndarray | torch.Tensor, frames: int = 300, fps: float = 30.0,
                  batch_size: int = 256, lengths: np.ndarray | list[int] | None = None) -> np.ndarray:
    """Normalised fbank windows ``[W, N, n_mels]`` -> the timing stream ``[W, frames, 2]`` float32
    (see the module docstring). The first ``frames × 100 / fps`` fbank frames are used (zero-padded when
    shorter). ``lengths [W]``: each window's real fbank frames; past them its last real frame is repeated
    (none: every frame is real)."""
    need = int(round(frames * FBANK_FRAMES_PER_SECOND / fps))
    if lengths is not None and len(lengths) != len(fbank):
        raise ValueError(f"timing_stream: {len(lengths)} lengths for {len(fbank)} windows")
    out = []
    for i in range(0, len(fbank), batch_size):
        part = fbank[i: i + batch_size]  # memory-mapped windows are read a batch at a time
        part = part.float() if isinstance(part, torch.Tensor) else torch.from_numpy(np.asarray(part, np.float32))
        if part.dim() != 3:
            raise ValueError(f"timing_stream expects fbank windows [W, N, n_mels], got {tuple(part.shape)}")
        part = part[:, :need]
        if part.shape[1] < need:
            part = F.pad(part, (0, 0, 0, need - part.shape[1]))
        if lengths is not None:  # repeat each window's last real frame past its end
            last = torch.as_tensor(np.asarray(lengths[i: i + batch_size]), dtype=torch.long).clamp(0, need) - 1
            rows = torch.minimum(torch.arange(need)[None, :], last[:, None].clamp_min(0))  # [B, need]
            part = torch.gather(part, 1, rows[..., None].expand(-1, -1, part.shape[-1]))
            part = torch.where((last >= 0)[:, None, None], part, torch.zeros_like(part))
        loudness = part.mean(dim=-1)
        flux = F.pad((part[:, 1:] - part[:, :-1]).clamp_min(0.0).mean(dim=-1), (1, 0))
        stream = torch.stack([loudness, flux], dim=1)  # [B, 2, need]
        stream = F.adaptive_avg_pool1d(stream, frames)
        stream = stream - stream.mean(dim=-1, keepdim=True)
        std = stream.std(dim=-1, keepdim=True)
        stream = torch.where(std > 1e-6, stream / std.clamp_min(1e-6), torch.zeros_like(stream))
        out.append(stream.transpose(1, 2).contiguous().cpu().numpy())
    return np.concatenate(out) if out else np.zeros((0, frames, len(TIMING_FEATURES)), np.float32)
