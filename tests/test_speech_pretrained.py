"""Starting the speech encoders from pretrained weights (DeiT, AST layouts) and their one-line errors."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from emogesture.errors import EmogestureError, InputFileError
from emogesture.models.pretrained import (
    adapt_ast_checkpoint, adapt_deit_to_audio, init_encoder_from_pretrained, load_deit_state_dict,
)
from emogesture.models.vit import (AudioViT, ViTConfig)


def _gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def _synthetic_deit(depth: int = 2, width: int = 768) -> dict[str, torch.Tensor]:
    """Random tensors in timm's deit_base_distilled_patch16_384 layout (reduced depth)."""
    g = _gen(6)
    shapes = {"patch_embed.proj.weight": [width, 3, 16, 16], "patch_embed.proj.bias": [width],
              "cls_token": [1, 1, width], "dist_token": [1, 1, width], "pos_embed": [1, 2 + 24 * 24, width],
              "norm.weight": [width], "norm.bias": [width], "head.weight": [1000, width], "head.bias": [1000],
              "head_dist.weight": [1000, width], "head_dist.bias": [1000]}
    sd = {k: torch.randn(*shape, generator=g) for k, shape in shapes.items()}
    shapes = {"norm1": [width], "attn.qkv": [3 * width, width], "attn.proj": [width, width], "norm2": [width],
              "mlp.fc1": [4 * width, width], "mlp.fc2": [width, 4 * width]}
    for i in range(depth):
        for mod, shape in shapes.items():
            sd[f"blocks.{i}.{mod}.weight"] = torch.randn(*shape, generator=g)
            sd[f"blocks.{i}.{mod}.bias"] = torch.randn(shape[0], generator=g)
    return sd


def _time_interp(grid: np.ndarray, size: int) -> np.ndarray:
    """Linear resampling of the last axis with half-pixel centres, written out by hand."""
    n = grid.shape[-1]
    src = np.clip((np.arange(size) + 0.5) * n / size - 0.5, 0, n - 1)
    i0 = np.floor(src).astype(int)
    i1 = np.minimum(i0 + 1, n - 1)
    w = src - i0
    return grid[..., i0] * (1 - w) + grid[..., i1] * w


@pytest.fixture(scope="module")
def deit_and_vit():
    sd = _synthetic_deit()
    vit = AudioViT(ViTConfig(width=768, depth=2, heads=12))
    init_encoder_from_pretrained(vit, adapt_deit_to_audio(sd, vit.config))
    return sd, vit


def test_deit_weights_land_where_they_should(deit_and_vit):
    sd, vit = deit_and_vit
    got = vit.state_dict()
    assert torch.allclose(got["patch_embed.proj.weight"], sd["patch_embed.proj.weight"].mean(1, keepdim=True))
    for key in ("patch_embed.proj.bias", "cls_token", "dist_token", "norm.weight", "blocks.1.attn.qkv.weight",
                "blocks.0.mlp.fc2.bias", "blocks.1.norm2.weight"):
        assert torch.equal(got[key], sd[key]), key
    pos, old = got["pos_embed"], sd["pos_embed"]
    assert pos.shape == (1, 2 + 12 * 101, 768)
    assert torch.equal(pos[:, :2], old[:, :2])
    new_grid = pos[0, 2:].reshape(12, 101, 768)
    old_grid = old[0, 2:].reshape(24, 24, 768)
    # frequency: centre crop rows 6..17; time: the end columns map exactly onto the old ones
    assert torch.allclose(new_grid[0, 0], old_grid[6, 0]) and torch.allclose(new_grid[11, 100], old_grid[17, 23])
    assert torch.allclose(new_grid[0, 100], old_grid[6, 23]) and torch.allclose(new_grid[11, 0], old_grid[17, 0])
    expected = _time_interp(old_grid[6:18].permute(0, 2, 1).numpy().astype(np.float64), 101)
    assert np.allclose(new_grid.permute(0, 2, 1).numpy(), expected, atol=1e-5)


def test_deit_sum_option_and_interpolated_frequency():
    sd = _synthetic_deit(depth=1, width=64)
    cfg = ViTConfig(width=64, depth=1, heads=2)
    out = adapt_deit_to_audio(sd, cfg, channel_reduce="sum", freq_resize="interpolate")
    assert torch.allclose(out["patch_embed.proj.weight"], sd["patch_embed.proj.weight"].sum(1, keepdim=True))
    grid = out["pos_embed"][0, 2:].reshape(12, 101, 64)
    old = sd["pos_embed"][0, 2:].reshape(24, 24, 64)
    assert torch.allclose(grid[0, 0], old[:2, 0].mean(0), atol=1e-5)  # 24 -> 12 averages row pairs
    assert not any(k.startswith("head") for k in out)


def test_pretrained_key_errors_are_clear():
    sd = _synthetic_deit(depth=1, width=64)
    vit = AudioViT(ViTConfig(width=64, depth=1, heads=2))
    adapted = adapt_deit_to_audio(sd, vit.config)
    missing = {k: v for k, v in adapted.items() if k != "blocks.0.mlp.fc2.bias"}
    with pytest.raises(EmogestureError, match=r"lack 'blocks\.0\.mlp\.fc2\.bias' \(expected shape \[64\]\)"):
        init_encoder_from_pretrained(vit, missing)
    wrong = dict(adapted, **{"norm.weight": torch.zeros(70)})
    with pytest.raises(EmogestureError, match=r"'norm\.weight' has shape \[70\], the encoder expects \[64\]"):
        init_encoder_from_pretrained(vit, wrong)
    with pytest.raises(EmogestureError, match=r"12 key\(s\) the encoder does not have, e.g. .blocks\.1\."):
        init_encoder_from_pretrained(vit, adapt_deit_to_audio(_synthetic_deit(depth=2, width=64), vit.config))
    with pytest.raises(EmogestureError, match=r"shape \[64, 3, 16, 16\]; the encoder uses 32x32"):
        adapt_deit_to_audio(sd, ViTConfig(width=64, depth=1, heads=2, patch=32, stride=32))


def test_load_state_dict_files(tmp_path):
    from safetensors.torch import save_file

    sd = _synthetic_deit(depth=1, width=32)
    torch.save({"model": sd, "epoch": 3}, tmp_path / "deit.pth")
    save_file(sd, str(tmp_path / "deit.bin"))  # safetensors content under another name
    for name in ("deit.pth", "deit.bin"):
        loaded = load_deit_state_dict(tmp_path / name)
        assert set(loaded) == set(sd) and all(torch.equal(loaded[k], sd[k]) for k in sd)
    missing = tmp_path / "nope.pth"
    with pytest.raises(InputFileError) as err:
        load_deit_state_dict(missing)
    assert str(err.value) == f"{missing}: pretrained weights file not found"
    (tmp_path / "junk.pth").write_bytes(b"not a checkpoint at all")
    with pytest.raises(InputFileError) as err:
        load_deit_state_dict(tmp_path / "junk.pth")
    assert str(err.value).startswith(f"{tmp_path / 'junk.pth'}: cannot read") and "\n" not in str(err.value)


def test_ast_checkpoint_copies_or_resizes():
    g = _gen(7)
    cfg = ViTConfig(width=32, depth=1, heads=2)
    vit = AudioViT(cfg)
    ast = {f"module.v.{k}": torch.randn(v.shape, generator=g) for k, v in vit.state_dict().items()}
    ast["module.mlp_head.1.weight"] = torch.randn(527, 32, generator=g)
    init_encoder_from_pretrained(vit, adapt_ast_checkpoint(ast, cfg))
    assert all(torch.equal(v, ast[f"module.v.{k}"]) for k, v in vit.state_dict().items())
    short = dict(ast, **{"module.v.pos_embed": torch.randn(1, 2 + 12 * 50, 32, generator=g)})  # 512 frames
    pos = adapt_ast_checkpoint(short, cfg)["pos_embed"]
    old = short["module.v.pos_embed"][0, 2:].reshape(12, 50, 32)
    new = pos[0, 2:].reshape(12, 101, 32)
    assert torch.allclose(new[:, 0], old[:, 0]) and torch.allclose(new[:, 100], old[:, 49])
    expected = _time_interp(old.permute(0, 2, 1).numpy().astype(np.float64), 101)
    assert np.allclose(new.permute(0, 2, 1).numpy(), expected, atol=1e-5)
