"""How a trained gesture model generates, apart from what it learned (docs/design.md, 'Generation and editing').

A :class:`GenerationConfig` is stored with every gesture model (the ``generation`` section of its JSON),
set by the preset it was trained with and changed without retraining: per call
(``GesturePipeline.generate(..., generation=...)``), or stored anew with ``emogesture bundle --set``.
The architecture configs (:class:`~emogesture.models.gesture.GestureModelConfig`) hold none of it.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from emogesture.config import apply_overrides, to_dict
from emogesture.errors import ConfigError
from emogesture.types import FPS

#: Where models saved before the generation settings had their own section kept them: ``(section of the
#: architecture config, its key) -> GenerationConfig field``. Read when such a model is loaded.
LEGACY_KEYS = {("vae", "timing_guidance"): "timing_guidance", ("vae", "output_smoothing"): "output_smoothing",
               ("vae", "output_lowpass_hz"): "output_lowpass_hz",
               ("diffusion", "num_inference_steps"): "num_inference_steps",
               ("diffusion", "residual_scale"): "residual_scale"}


#: :attr:`GenerationConfig.timing_guidance_on`'s values.
TIMING_GUIDANCE_ON = ("stream", "onsets")


@dataclass
class GenerationConfig:
    """The steps after training, in the order they run (:mod:`emogesture.pipeline.postprocess`)."""

    #: DDIM steps of the sampling loop (paper: 50).
    num_inference_steps: int = 50
    #: Scale of the calibrated residual noise added to each DDIM sample (not in the paper; 0 = off). It
    #: acts only on a model that carries a calibration (:mod:`emogesture.diffusion.residual`).
    residual_scale: float = 0.0
    #: For a decoder that reads the speech's timing stream: its output is
    #: ``D(z, zeros) + w · (D(z, stream) − D(z, zeros))``, the stream's part scaled by ``w`` (guidance on
    #: the stream, as classifier-free guidance does on a condition; 1 = as trained).
    timing_guidance: float = 1.0
    #: What the decoding that guidance extrapolates from does not hear: ``"stream"``, the whole timing
    #: stream (``D(z, zeros)`` above); ``"onsets"``, only its onset strength, the loudness heard in both
    #: decodings, so that guidance scales when the syllables start and not where the speech is loud (the
    #: loudness moved the arms up to a second early, in time with audio a second off as well as with the
    #: window's own; experiments/rhythm/README.md, "When the arms move").
    timing_guidance_on: str = "stream"
    #: σ, in frames, of a Gaussian smoothing of the decoded features over time (0 = none).
    output_smoothing: float = 0.0
    #: Cutoff, in Hz at the motion's 30 fps, of a zero-phase low-pass over the decoded features (0 = none;
    #: after ``output_smoothing`` when both are set).
    output_lowpass_hz: float = 0.0
    #: Samples drawn per window of a long audio, one kept per window so that the worst seam moves least
    #: (1 = every window independent).
    seam_candidates: int = 4
    #: Seconds between the starts of a long audio's 10-s windows (7: neighbours overlap by 3 s).
    hop_seconds: float = 7.0
    #: Whether the speech model hears a noisy recording with its steady background noise taken out
    #: (:mod:`emogesture.audio.noise`; a recording in quiet surroundings is heard as it is either way).
    noise_suppression: bool = True
    #: The emotion heard in a window is the mean of three hearings: as recorded and with the voice moved
    #: this many semitones up and down (pitch and formants, tempo kept), so that a voice pitched unlike
    #: the training voices is not heard by its pitch alone (0 = heard once). Only what is heard (labels,
    #: probabilities, timelines) changes; the latents the gesture model is given are the recording's own.
    #: Each extra hearing is one more pass of the emotion encoder (milliseconds with the bundled model; a
    #: third of the speech encoders' time each with the paper's). A live stream hears once.
    perception_semitones: float = 3.0

    def __post_init__(self) -> None:
        if self.num_inference_steps < 1 or self.seam_candidates < 1:
            raise ConfigError(f"generation: num_inference_steps and seam_candidates must be ≥ 1, got "
                              f"{self.num_inference_steps} and {self.seam_candidates}")
        if min(self.residual_scale, self.timing_guidance, self.output_smoothing) < 0:
            raise ConfigError(f"generation: residual_scale, timing_guidance and output_smoothing must be ≥ 0, got "
                              f"{self.residual_scale}, {self.timing_guidance}, {self.output_smoothing}")
        if self.timing_guidance_on not in TIMING_GUIDANCE_ON:
            raise ConfigError(f"generation: timing_guidance_on must be one of {', '.join(TIMING_GUIDANCE_ON)}, "
                              f"got {self.timing_guidance_on!r}")
        if not 0 <= self.output_lowpass_hz < FPS / 2:
            raise ConfigError(f"generation: output_lowpass_hz must be 0 (off) or below {FPS / 2:g} Hz (half the "
                              f"{FPS} fps), got {self.output_lowpass_hz}")
        if not 0 <= self.perception_semitones <= 12:
            raise ConfigError(f"generation: perception_semitones must be in [0, 12] (0: heard once), got "
                              f"{self.perception_semitones}")
        if not 0 < self.hop_seconds <= 10:
            raise ConfigError(f"generation: hop_seconds must be in (0, 10] (windows are 10 s), got {self.hop_seconds}")

    @classmethod
    def preset(cls, name: str, variant: str = "joint") -> "GenerationConfig":
        """``paper``: 50 DDIM steps and nothing after sampling. ``tiny``: 10 DDIM steps, half the calibrated
        residual noise, and — for the variants whose decoder hears the speech's timing (``joint``,
        ``disjoint``) — timing guidance 6 on the onsets (``timing_guidance_on="onsets"``) with a 4-Hz
        low-pass, chosen together on the val split (``experiments/rhythm/reports/rhythm/onset_guidance_val.md``)."""
        if name == "paper":
            return cls()
        if name == "tiny":
            timing = (dict(timing_guidance=6.0, timing_guidance_on="onsets", output_lowpass_hz=4.0)
                      if variant in ("joint", "disjoint") else {})
            return cls(num_inference_steps=10, residual_scale=0.5, **timing)
        raise ConfigError(f"unknown generation preset {name!r}; known: paper, tiny")

    def with_overrides(self, overrides: list[str]) -> "GenerationConfig":
        """A copy with ``key=value`` overrides (e.g. ``timing_guidance=3``); keys: the fields."""
        names = [f.name for f in fields(self)]
        for item in overrides:
            if "=" not in item or item.split("=", 1)[0].strip() not in names:
                raise ConfigError(f"{item!r}: a generation setting is key=value with key one of {', '.join(names)}")
        return apply_overrides(GenerationConfig, to_dict(self), overrides)


def split_legacy_settings(config: dict) -> tuple[dict, dict]:
    """A gesture model's stored architecture config (a dict) -> (the same without the generation settings
    that older models kept inside it, those settings by :class:`GenerationConfig` field)."""
    config = {k: dict(v) if isinstance(v, dict) else v for k, v in config.items()}
    found = {}
    for (section, key), name in LEGACY_KEYS.items():
        if key in config.get(section, {}):
            found[name] = config[section].pop(key)
    return config, found
