"""How models run at inference: the device, the precision (float32, or bfloat16 autocast) and per-stage timing.

``--precision auto`` (the default of ``emogesture generate``) takes bf16 autocast where bf16 matrix
products are native — a GPU that supports bf16, or a CPU with ``avx512_bf16`` or AMX — and float32
elsewhere (a CPU without them emulates bf16, slower than float32). ``fp32`` keeps the exact path.
Under bf16 the matrix products of the audio encoders, the denoiser and the motion decoder run in
bf16; their outputs are returned in float32. The drift this causes is measured by ``bench/``.

CPU speed-ups beyond plain torch (oneDNN's packed bf16 Linear weights and fused Linear + GELU, through
torch's private ``torch.ops.mkldnn`` ops; a blocked bf16 attention, :func:`emogesture.kernels.attention`)
are all switched by :func:`acceleration_enabled`: off with ``EMOGESTURE_ACCELERATION=0`` in the
environment (or :func:`set_acceleration`), and off by themselves where this torch lacks the private ops
(:func:`private_ops_available`). Plain torch then runs the same arithmetic, within bf16 rounding.
"""

from __future__ import annotations

import os
import threading
import time
from contextlib import contextmanager
from functools import lru_cache, partial

import torch
import torch.nn.functional as F
from torch import nn

from emogesture.errors import EmogestureError

PRECISIONS = ("auto", "fp32", "bf16")
DEVICES = ("auto", "cpu", "cuda")


@lru_cache(maxsize=1)
def cpu_flags() -> frozenset[str]:
    """The CPU's feature flags (``/proc/cpuinfo``; empty where it cannot be read)."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("flags"):
                    return frozenset(line.split(":", 1)[1].split())
    except OSError:
        pass
    return frozenset()


def native_bf16(device: str | torch.device) -> bool:
    """True where bf16 matrix products run natively on ``device``: NVIDIA GPUs from compute capability
    8.0 (Ampere) on, not the older ones where torch only emulates bf16; on ROCm, what torch reports
    without emulation; CPUs with avx512_bf16 or AMX."""
    device = torch.device(device)
    if device.type == "cuda":
        if not torch.cuda.is_available():
            return False
        if torch.version.hip:
            return torch.cuda.is_bf16_supported(including_emulation=False)
        return torch.cuda.get_device_capability(device) >= (8, 0)
    return bool({"avx512_bf16", "amx_bf16"} & cpu_flags())


def resolve_device(name: str | None) -> str:
    """``auto``/None -> ``cuda`` when a GPU is visible, else ``cpu``; ``cuda`` without one is an error."""
    name = (name or "auto").lower()
    if name == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if name == "cuda" or name.startswith("cuda:"):
        index = name[5:]  # "" for cuda
        if name != "cuda" and not index.isdigit():
            raise EmogestureError(f"--device {name!r}: a GPU is cuda or cuda:N, N a number")
        if not torch.cuda.is_available():
            raise EmogestureError(f"--device {name}: no CUDA GPU is visible to torch (this torch is "
                                  f"{torch.__version__}); use --device cpu")
        count = torch.cuda.device_count()
        if index and int(index) >= count:
            raise EmogestureError(f"--device {name}: torch sees {count} GPU{'s' if count != 1 else ''} "
                                  f"(cuda:0{f' to cuda:{count - 1}' if count > 1 else ''})")
        return name
    if name == "cpu":
        return name
    raise EmogestureError(f"--device {name!r}: choose one of {', '.join(DEVICES)} (or cuda:N)")


def process_device(accelerator: str) -> str:
    """The device of this training process for ``--device cpu|cuda|gpu|auto``: under DDP each process's
    own GPU (``LOCAL_RANK``, set for the processes Lightning starts, or SLURM's ``SLURM_LOCALID``; modulo
    the GPUs it sees), not all of them the first."""
    if accelerator == "cpu":
        return "cpu"
    device = resolve_device("cuda" if accelerator == "gpu" else accelerator)
    if device != "cuda":
        return device
    local = int(os.environ.get("LOCAL_RANK", os.environ.get("SLURM_LOCALID", 0)))
    return f"cuda:{local % torch.cuda.device_count()}"


def resolve_precision(precision: str | None, device: str | torch.device) -> str:
    """``auto``/None -> ``bf16`` where :func:`native_bf16`, else ``fp32``; ``fp32``/``bf16`` as asked."""
    precision = (precision or "auto").lower()
    if precision not in PRECISIONS:
        raise EmogestureError(f"--precision {precision!r}: choose one of {', '.join(PRECISIONS)}")
    if precision == "auto":
        return "bf16" if native_bf16(device) else "fp32"
    return precision


#: The environment variable that switches the CPU speed-ups off (``0``, ``off``, ``false`` or ``no``).
ACCELERATION_ENV = "EMOGESTURE_ACCELERATION"
_acceleration: bool | None = None  # set_acceleration's choice; None: the environment decides
#: the private oneDNN ops the speed-ups call (not part of torch's public API; other builds may lack them)
PRIVATE_OPS = ("_linear_pointwise", "_reorder_linear_weight", "_is_mkldnn_bf16_supported")


def set_acceleration(enabled: bool | None) -> None:
    """Switch the CPU speed-ups on or off for this process (None: as ``EMOGESTURE_ACCELERATION`` says).
    Weights already packed (:func:`hold_bf16_weights`) stay packed; load the model again."""
    global _acceleration
    _acceleration = enabled


def acceleration_enabled() -> bool:
    """Whether the CPU speed-ups may run: :func:`set_acceleration`'s choice, else the environment's
    (on unless ``EMOGESTURE_ACCELERATION`` is ``0``, ``off``, ``false`` or ``no``)."""
    if _acceleration is not None:
        return _acceleration
    return os.environ.get(ACCELERATION_ENV, "1").strip().lower() not in ("0", "off", "false", "no")


def private_ops_available() -> bool:
    """Whether this torch has every oneDNN op of :data:`PRIVATE_OPS` (looked up each time: cheap)."""
    for name in PRIVATE_OPS:
        try:
            getattr(torch.ops.mkldnn, name)
        except (AttributeError, RuntimeError):
            return False
    return True


@lru_cache(maxsize=1)
def amx_bf16() -> bool:
    """True on a CPU with AMX bf16 tiles (Intel Xeon from Sapphire Rapids on): its bf16 products ran
    about 2800 GFLOP/s on 2 cores, 7 x an AVX-512-bf16 CPU's, and torch's fused attention kernel is
    the faster one there (:func:`emogesture.kernels.attention`)."""
    return "amx_bf16" in cpu_flags()


def packs_bf16_weights(device: str | torch.device) -> bool:
    """True where :func:`bf16_weights` can pack Linear weights for oneDNN (a CPU with native bf16)."""
    return torch.device(device).type == "cpu" and _onednn_bf16()


def _onednn_bf16() -> bool:
    """Whether the oneDNN bf16 speed-ups run: switched on, the private ops present, a CPU with native bf16."""
    return acceleration_enabled() and private_ops_available() and _onednn_bf16_native()


@lru_cache(maxsize=1)
def _onednn_bf16_native() -> bool:
    return native_bf16("cpu") and torch.backends.mkldnn.is_available() and torch.ops.mkldnn._is_mkldnn_bf16_supported()


def linear_gelu(layer: nn.Linear, x: torch.Tensor, approximate: str = "none") -> torch.Tensor | None:
    """``gelu(layer(x))`` as one oneDNN product with the GELU applied to its float32 sums before they are
    rounded, where that can run: without autograd, on a CPU with native bf16, with the bf16 weights of
    :func:`bf16_weights` (packed, if it packed them). None elsewhere: the caller runs the two steps.

    Writing the product's bf16 output and then reading it again for the GELU took 4 % of a paper
    encoder's time (bench/results/cpu.md, "bf16 generation nearer its floor")."""
    weight = layer.__dict__.get("packed_weight")
    if weight is None and layer.weight.dtype == torch.bfloat16:
        weight = layer.weight
    if weight is None or torch.is_grad_enabled() or x.device.type != "cpu" or not _onednn_bf16():
        return None
    try:
        return _onednn_linear(x, weight, layer.bias, "gelu", approximate)
    except RuntimeError:  # a private op that changed its signature: the caller runs the two steps
        return None


def _onednn_linear(x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor | None, post_op: str = "none",
                   algorithm: str = "") -> torch.Tensor:
    """oneDNN's bf16 product ``x [..., in] -> [..., out]`` with a post-op on its float32 sums."""
    return torch.ops.mkldnn._linear_pointwise(x.to(torch.bfloat16), weight, bias, post_op, [], algorithm)


def _packed_linear(layer: nn.Linear, x: torch.Tensor) -> torch.Tensor:
    """``layer(x)`` in bf16 through oneDNN with the weight :func:`bf16_weights` packed once (``x [..., in]
    -> [..., out]``); with autograd or off the CPU, the plain product of the layer's bf16 weight."""
    if x.device.type != "cpu" or (torch.is_grad_enabled() and x.requires_grad) or not _onednn_bf16():
        return F.linear(x, layer.weight, layer.bias)
    try:
        return _onednn_linear(x, layer.packed_weight, layer.bias)
    except RuntimeError:  # a private op that changed its signature: the plain product of the bf16 weight
        return F.linear(x.to(layer.weight.dtype), layer.weight, layer.bias)


@contextmanager
def bf16_weights(precision: str, *modules: nn.Module, pack: bool = False):
    """Inside this context the Linear layers of ``modules`` hold bf16 copies of their weights and biases
    when ``precision == "bf16"`` (the float32 parameters are put back on exit); else it does nothing.

    Autocast would cast them to bf16 at every call, the same numbers: in a 50-step sampling loop those
    casts took 14 % of the time. Enter it once around a loop of :func:`autocast` batches.

    ``pack``: on a CPU with native bf16 (:func:`packs_bf16_weights`) each ``nn.Linear`` also gets its
    weight packed once into oneDNN's blocked layout and calls oneDNN's product with it, as inference
    libraries for CPUs do: a plain product repacks the weight at every call. It pays where each layer
    runs many times, as the denoiser does in a sampling loop: the paper denoiser's 180-row products ran
    10–15 % faster, and packing its 87 M weights took 0.2 s. Packing the paper speech model took 0.7–1.4 s,
    as much as it saved on a 60-s clip (bench/results/cpu.md, "bf16 generation nearer its floor"). The
    numbers are autocast's to bf16 rounding (the same products, summed in another order).
    """
    saved, patched = [], []
    try:
        if precision == "bf16":
            _bf16_linears(modules, pack, saved, patched)
        else:
            refuse_held_weights(*modules)
        yield
    finally:
        for layer in patched:
            del layer.forward, layer.packed_weight
        for layer, weight, bias in saved:
            layer.weight, layer.bias = weight, bias


def hold_bf16_weights(precision: str, *modules: nn.Module, pack: bool = False) -> None:
    """For inference only: give the Linear layers of ``modules`` their bf16 weights (packed, with
    ``pack``, as :func:`bf16_weights` does) once and for good when ``precision == "bf16"``, dropping the
    float32 ones; else nothing. :func:`bf16_weights` then finds nothing left to do, so a pipeline that
    holds its models this way stops paying the casts (and the packing) at every call — on the tiny
    model, 14 ms of a 55-ms 4-s clip — and its weights take half the memory.

    The modules can no longer run in float32 (a float32 input meets a bf16 weight) nor be saved as
    trained: hold only models loaded for the pipeline's own use."""
    if precision == "bf16":
        _bf16_linears(modules, pack)


def refuse_held_weights(*modules: nn.Module) -> None:
    """A one-line error when ``modules`` hold bf16 weights (:func:`hold_bf16_weights`) but are to run in
    float32, instead of torch's dtype mismatch from inside a product."""
    if any(isinstance(layer, nn.Linear) and layer.weight.dtype == torch.bfloat16
           for module in modules for layer in module.modules()):
        raise EmogestureError("this model holds bf16 weights (loaded for a bf16 pipeline): run it with precision "
                              "bf16, or load it again for float32")


def _bf16_linears(modules: tuple[nn.Module, ...], pack: bool, saved: list | None = None,
                  patched: list | None = None) -> None:
    """Give every float32 ``nn.Linear`` of ``modules`` bf16 weights and biases (and, with ``pack`` where
    :func:`packs_bf16_weights`, a packed weight and a forward using it); append what was replaced,
    ``(layer, weight, bias)``, to ``saved`` and the layers whose forward was patched to ``patched``
    (None: keep nothing, so each float32 weight is freed as soon as it is replaced)."""
    for module in modules:
        for layer in module.modules():
            if isinstance(layer, nn.Linear) and layer.weight.dtype == torch.float32:
                if saved is not None:
                    saved.append((layer, layer.weight, layer.bias))
                layer.weight = nn.Parameter(layer.weight.detach().to(torch.bfloat16), requires_grad=False)
                if layer.bias is not None:
                    layer.bias = nn.Parameter(layer.bias.detach().to(torch.bfloat16), requires_grad=False)
                if pack and type(layer) is nn.Linear and "forward" not in vars(layer) \
                        and packs_bf16_weights(layer.weight.device):
                    layer.packed_weight = torch.ops.mkldnn._reorder_linear_weight(layer.weight.detach())
                    layer.forward = partial(_packed_linear, layer)
                    if patched is not None:
                        patched.append(layer)


_FLOAT32_LOCK = threading.Lock()
_float32_depth = 0
_float32_saved: dict[str, object] = {}


def _cudnn_legacy_tf32() -> bool | None:
    """``torch.backends.cudnn.allow_tf32``, or None where torch refuses to read it (the process set
    cuDNN's TF32 through the per-operator ``fp32_precision`` settings, torch 2.9 on)."""
    try:
        return torch.backends.cudnn.allow_tf32
    except RuntimeError:
        return None


def _float32_enter() -> None:
    """Turn TF32 off for CUDA matrix products and cuDNN convolutions, keeping torch's older flags and its
    per-operator ``fp32_precision`` settings (torch 2.9 on) in agreement, as torch checks at every
    product; what they were is kept in ``_float32_saved``."""
    cudnn, saved = torch.backends.cudnn, _float32_saved
    saved["matmul"] = torch.get_float32_matmul_precision()
    saved["cudnn"] = _cudnn_legacy_tf32()
    per_op = {"cuda.matmul": torch.backends.cuda.matmul, "cudnn.conv": getattr(cudnn, "conv", None),
              "cudnn.rnn": getattr(cudnn, "rnn", None)}
    saved["per_op"] = {k: (v, v.fp32_precision) for k, v in per_op.items() if hasattr(v, "fp32_precision")}
    torch.set_float32_matmul_precision("highest")  # sets cuda.matmul's fp32_precision to match
    if saved["cudnn"] is not None:
        cudnn.allow_tf32 = False  # sets conv's and rnn's to match
    elif "cudnn.conv" in saved["per_op"]:
        cudnn.conv.fp32_precision = "ieee"  # what convolutions read; the older flag stays unreadable


def _float32_exit() -> None:
    saved = _float32_saved
    torch.set_float32_matmul_precision(saved["matmul"])
    if saved["cudnn"] is not None:
        torch.backends.cudnn.allow_tf32 = saved["cudnn"]
    for backend, value in saved["per_op"].values():
        backend.fp32_precision = value
    saved.clear()


@contextmanager
def exact_float32(device: str | torch.device):
    """A context in which float32 stays float32 on a GPU: cuDNN's convolutions (the patch embedding,
    the motion decoder's filters) and the matrix products run without TF32 (torch allows TF32 in
    convolutions by default, and training sets ``float32_matmul_precision("high")``, TF32 in products).

    The settings are process-wide: they are changed when the first thread enters and put back, exactly
    as they were, when the last one leaves (a bf16 run in another thread meanwhile keeps its bf16
    products). Nothing changes on a CPU."""
    global _float32_depth
    if torch.device(device).type != "cuda":
        yield
        return
    with _FLOAT32_LOCK:
        if _float32_depth == 0:
            _float32_enter()
        _float32_depth += 1
    try:
        yield
    finally:
        with _FLOAT32_LOCK:
            _float32_depth -= 1
            if _float32_depth == 0:
                _float32_exit()


@contextmanager
def autocast(precision: str, device: str | torch.device, *modules: nn.Module):
    """A context that runs matrix products in bf16 when ``precision == "bf16"``, ``modules`` holding bf16
    weights inside it (:func:`bf16_weights`); under any other precision, float32 throughout
    (:func:`exact_float32`)."""
    if precision != "bf16":
        with exact_float32(device):
            yield
        return
    with bf16_weights(precision, *modules), torch.autocast(device_type=torch.device(device).type,
                                                           dtype=torch.bfloat16):
        yield


class StageTimes(dict):
    """Wall seconds per named stage, accumulated: ``with times.stage("sampling"): ...``."""

    def __init__(self, device: str | torch.device = "cpu") -> None:
        super().__init__()
        self.device = torch.device(device)

    @contextmanager
    def stage(self, name: str):
        self._sync()
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self._sync()
            self[name] = self.get(name, 0.0) + time.perf_counter() - t0

    def _sync(self) -> None:
        if self.device.type == "cuda":
            torch.cuda.synchronize(self.device)


@contextmanager
def maybe_stage(times: StageTimes | None, name: str):
    """``times.stage(name)`` when timing, else nothing."""
    if times is None:
        yield
    else:
        with times.stage(name):
            yield
