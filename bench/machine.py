"""The machine a benchmark runs on, and its floor: the matrix throughput measured in the same run.

``describe()`` names the CPU (model, cores, the flags that matter for speed), the GPU if one is used,
and the torch version. ``matmul_throughput(dtype)`` times a large square matrix product (best of a
few repeats, after a warm-up) and returns GFLOP/s; ``floors`` takes the best over a few sizes: the
rate no model made of matrix products beats on this machine, so FLOPs ÷ this rate is a stage's floor.
"""

from __future__ import annotations

import json
import os
import platform
import time

import torch

from emogesture.runtime import cpu_flags

SPEED_FLAGS = ("avx2", "avx512f", "avx512_bf16", "amx_bf16", "amx_tile", "fma")


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def describe(device: str = "cpu") -> dict:
    flags = cpu_flags()
    out = {"cpu": cpu_model(), "cores": os.cpu_count(), "torch_threads": torch.get_num_threads(),
           "cpu_flags": [f for f in SPEED_FLAGS if f in flags], "torch": torch.__version__,
           "python": platform.python_version(), "device": device}
    if device.startswith("cuda") and torch.cuda.is_available():
        out["gpu"] = torch.cuda.get_device_name(device)
    return out


def synchronize(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize(device)


def matmul_throughput(dtype: torch.dtype = torch.float32, size: int = 2048, repeats: int = 5,
                      device: str = "cpu") -> float:
    """GFLOP/s of ``[size, size] @ [size, size]`` in ``dtype`` (best of ``repeats``)."""
    if device.startswith("cuda"):
        size = max(size, 8192)
    g = torch.Generator(device="cpu").manual_seed(0)
    a = torch.randn(size, size, generator=g).to(device=device, dtype=dtype)
    b = torch.randn(size, size, generator=g).to(device=device, dtype=dtype)
    with torch.inference_mode():
        a @ b  # warm-up
        synchronize(device)
        best = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            a @ b
            synchronize(device)
            best = min(best, time.perf_counter() - t0)
    return 2 * size**3 / best / 1e9


def floors(device: str = "cpu", sizes: tuple[int, ...] = (2048, 4096)) -> dict:
    """Measured matrix throughput, GFLOP/s: ``{"fp32": ..., "bf16": ...}``, the best over ``sizes``
    (on the 2-core reference machine a 4096² product runs 1.6× faster than a 2048² one, and the
    paper's audio encoders reach the larger rate: a floor below what the models achieve is no floor)."""
    return {name: round(max(matmul_throughput(dtype, size=n, repeats=5 if name == "fp32" else 3, device=device)
                            for n in sizes), 1)
            for name, dtype in (("fp32", torch.float32), ("bf16", torch.bfloat16))}


def write_json(path, result: dict) -> None:
    """Write a benchmark's result as JSON at ``path`` (a ``pathlib.Path``; None = nowhere)."""
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    print(json.dumps({**describe(), "matmul_gflops": floors()}, indent=1))
