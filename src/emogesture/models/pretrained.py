"""Optional pretrained initialisation of the audio ViTs (docs/design.md, 'Speech disentanglement model'): DeiT
(timm layout) or AST checkpoints.

The only module of :mod:`emogesture.models` that reads a file, and only a local one given by the user:
nothing is ever downloaded. ``load_deit_state_dict`` reads tensors; ``adapt_*`` turn an image (DeiT) or
AST state dict into one for :class:`~emogesture.models.vit.AudioViT`; ``init_encoder_from_pretrained``
loads it with strict key and shape checks.
"""

from __future__ import annotations

import math
from os import PathLike
from pathlib import Path

import torch
import torch.nn.functional as F

from emogesture.errors import EmogestureError, InputFileError
from emogesture.models.vit import AudioViT, ViTConfig

_WRAPPERS = ("model", "state_dict", "model_state_dict", "module")
#: Key prefixes of the classification heads, which the audio encoders do not use.
_IGNORED_PREFIXES = ("head.", "head_dist.", "fc_norm.", "pre_logits.")


def load_deit_state_dict(path: str | PathLike[str]) -> dict[str, torch.Tensor]:
    """Tensors of a local ``.pth``/``.pt`` (``torch.load(weights_only=True)``) or ``.safetensors`` file.

    The format is detected from the content. A checkpoint wrapping its weights under ``model`` or
    ``state_dict`` is unwrapped. Missing, unreadable or tensor-less files raise :class:`InputFileError`.
    """
    p = Path(path)
    if not p.is_file():
        raise InputFileError(p, "pretrained weights file not found")
    try:
        with open(p, "rb") as fh:
            head = fh.read(9)
        if len(head) == 9 and head[8:9] == b"{":  # safetensors: u64 header length, then JSON
            from safetensors.torch import load_file

            obj = load_file(str(p), device="cpu")
        else:
            obj = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001 - any reader failure is a bad file for the user
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        raise InputFileError(p, f"cannot read pretrained weights ({first})") from None
    while isinstance(obj, dict):
        inner = next((obj[k] for k in _WRAPPERS if isinstance(obj.get(k), dict)), None)
        if inner is None:
            break
        obj = inner
    if not isinstance(obj, dict) or not obj or not all(
        isinstance(k, str) and isinstance(v, torch.Tensor) for k, v in obj.items()
    ):
        raise InputFileError(p, "holds no state dict of named tensors")
    return dict(obj)


def _fit_axis(grid: torch.Tensor, axis: int, size: int, crop: bool) -> torch.Tensor:
    """Resize axis 2 (freq) or 3 (time) of ``grid [1, D, F, T]`` to ``size``.

    Shrinking with ``crop`` keeps the centre rows; otherwise linear interpolation (half-pixel centres,
    ``align_corners=False``), which maps the first and last positions exactly onto the old ones.
    """
    current = grid.shape[axis]
    if size == current:
        return grid
    if crop and size < current:
        start = (current - size) // 2
        return grid.narrow(axis, start, size)
    target = list(grid.shape[2:])
    target[axis - 2] = size
    return F.interpolate(grid, size=tuple(target), mode="bilinear", align_corners=False)


def resize_pos_grid(
    pos_grid: torch.Tensor, grid: tuple[int, int], freq_resize: str = "crop"
) -> torch.Tensor:
    """Resize a grid of patch positional embeddings ``[1, D, Fs, Ts]`` to ``grid`` = (F, T).

    Time is interpolated; frequency is centre-cropped (``freq_resize="crop"``, as AST does) or
    interpolated (``"interpolate"``). Returns ``[1, F * T, D]`` frequency-major.
    """
    if freq_resize not in ("crop", "interpolate"):
        raise EmogestureError(f"freq_resize must be 'crop' or 'interpolate', got {freq_resize!r}")
    dtype = pos_grid.dtype
    g = _fit_axis(pos_grid.float(), 3, grid[1], crop=False)
    g = _fit_axis(g, 2, grid[0], crop=freq_resize == "crop")
    return g.flatten(2).transpose(1, 2).contiguous().to(dtype)


def _reduce_channels(weight: torch.Tensor, config: ViTConfig, channel_reduce: str) -> torch.Tensor:
    if weight.dim() != 4 or tuple(weight.shape[2:]) != config.kernel:
        raise EmogestureError(
            f"pretrained patch kernel has shape {list(weight.shape)}; the encoder uses "
            f"{config.kernel[0]}x{config.kernel[1]} patches"
        )
    if weight.shape[1] == 1:
        return weight
    if channel_reduce == "mean":
        return weight.mean(dim=1, keepdim=True)
    if channel_reduce == "sum":
        return weight.sum(dim=1, keepdim=True)
    raise EmogestureError(f"channel_reduce must be 'mean' or 'sum', got {channel_reduce!r}")


def _adapt(
    sd: dict[str, torch.Tensor], config: ViTConfig, source_grid: tuple[int, int],
    channel_reduce: str, freq_resize: str,
) -> dict[str, torch.Tensor]:
    out: dict[str, torch.Tensor] = {}
    for key, value in sd.items():
        if key.startswith(_IGNORED_PREFIXES):
            continue
        if key == "patch_embed.proj.weight":
            value = _reduce_channels(value, config, channel_reduce)
        elif key == "pos_embed":
            n_src = 2 if "dist_token" in sd else 1
            if n_src < config.num_prefix:
                raise EmogestureError("pretrained weights have no [DIST] token but the encoder is distilled")
            fs, ts = source_grid
            if value.shape[1] != n_src + fs * ts:
                raise EmogestureError(
                    f"pretrained pos_embed has {value.shape[1]} tokens, not {n_src} + {fs}x{ts}"
                )
            prefix = value[:, : config.num_prefix]
            patches = value[:, n_src:].transpose(1, 2).reshape(1, -1, fs, ts)
            value = torch.cat([prefix, resize_pos_grid(patches, config.grid, freq_resize)], dim=1)
        elif key == "dist_token" and not config.distilled:
            continue
        out[key] = value
    return out


def adapt_deit_to_audio(
    state_dict: dict[str, torch.Tensor], vit_config: ViTConfig, channel_reduce: str = "mean",
    freq_resize: str = "crop",
) -> dict[str, torch.Tensor]:
    """A timm DeiT state dict (e.g. ``deit_base_distilled_patch16_384``) -> :class:`AudioViT` keys.

    RGB patch kernels ``[D, 3, 16, 16]`` are averaged (``channel_reduce="sum"``: summed) to
    ``[D, 1, 16, 16]``; the square positional grid (24×24) is resized to ``vit_config.grid`` (12×101);
    the [CLS]/[DIST] tokens and their positions, the blocks and the final norm are kept; ``head*`` dropped.
    """
    pos = state_dict.get("pos_embed")
    if pos is None:
        raise EmogestureError("pretrained weights lack 'pos_embed'")
    n_patches = pos.shape[1] - (2 if "dist_token" in state_dict else 1)
    side = math.isqrt(max(n_patches, 0))
    if side * side != n_patches:
        raise EmogestureError(f"DeiT pos_embed holds {n_patches} patches, not a square grid")
    return _adapt(state_dict, vit_config, (side, side), channel_reduce, freq_resize)


def adapt_ast_checkpoint(
    state_dict: dict[str, torch.Tensor], vit_config: ViTConfig,
    source_grid: tuple[int, int] | None = None, freq_resize: str = "crop",
) -> dict[str, torch.Tensor]:
    """An AST checkpoint (keys ``module.v.*``, one-channel kernels) -> :class:`AudioViT` keys.

    Its positional embeddings are copied when the patch count matches ``vit_config``; otherwise resized
    from ``source_grid`` (default: the encoder's frequency rows, time = the rest). ``mlp_head`` is dropped.
    """
    sd: dict[str, torch.Tensor] = {}
    for key, value in state_dict.items():
        k = key[len("module."):] if key.startswith("module.") else key
        if k.startswith("v."):
            sd[k[2:]] = value
    if "pos_embed" not in sd:
        raise EmogestureError("AST checkpoint lacks 'module.v.pos_embed' (is this an AST checkpoint?)")
    n_patches = sd["pos_embed"].shape[1] - (2 if "dist_token" in sd else 1)
    if source_grid is None:
        f = vit_config.grid[0]
        if n_patches == vit_config.num_patches:
            source_grid = vit_config.grid
        elif n_patches % f == 0:
            source_grid = (f, n_patches // f)
        else:
            raise EmogestureError(f"AST pos_embed holds {n_patches} patches; give its source_grid (freq, time)")
    return _adapt(sd, vit_config, tuple(source_grid), "mean", freq_resize)


def init_encoder_from_pretrained(encoder_vit: AudioViT, adapted_state_dict: dict[str, torch.Tensor]) -> None:
    """Copy ``adapted_state_dict`` into ``encoder_vit``; every key must exist with the same shape.

    Raises :class:`EmogestureError` naming the first missing, unexpected or mis-shaped key.
    """
    expected = encoder_vit.state_dict()
    for key, target in expected.items():
        if key not in adapted_state_dict:
            raise EmogestureError(f"pretrained weights lack {key!r} (expected shape {list(target.shape)})")
        got = adapted_state_dict[key]
        if tuple(got.shape) != tuple(target.shape):
            raise EmogestureError(
                f"pretrained weight {key!r} has shape {list(got.shape)}, the encoder expects {list(target.shape)}"
            )
    extra = sorted(set(adapted_state_dict) - set(expected))
    if extra:
        raise EmogestureError(
            f"pretrained weights hold {len(extra)} key(s) the encoder does not have, e.g. {extra[0]!r} "
            f"{list(adapted_state_dict[extra[0]].shape)}"
        )
    encoder_vit.load_state_dict(adapted_state_dict, strict=True)


def init_speech_model_from_pretrained(model, adapted_state_dict: dict[str, torch.Tensor]) -> None:
    """Initialise the ViTs of all three encoders of a ``SpeechDisentangler`` from the same weights."""
    for name in ("content_encoder", "emotion_encoder", "style_encoder"):
        init_encoder_from_pretrained(getattr(model, name).vit, adapted_state_dict)
