"""Files shipped inside the package: the bundled model and the demo's speech clips.

``model/`` holds the bundled ``tiny`` speech and gesture models and the evaluation suite's motion
feature extractor (``<kind>.safetensors`` + ``<kind>.json`` each, float16 weights), their
``SHA256SUMS`` and the model card ``MODEL_CARD.md``; ``demo/`` holds short synthetic speech clips.
`experiments/bundled_model.sh` (``make model``) rebuilds the model from scratch.
"""

from __future__ import annotations

from pathlib import Path

ASSETS = Path(__file__).resolve().parent
BUNDLED_MODEL = ASSETS / "model"
DEMO_CLIPS = ASSETS / "demo"


def bundled_model_file(kind: str) -> Path:
    """The JSON of the bundled model of ``kind`` (``speech``, ``gesture`` or ``extractor``)."""
    return BUNDLED_MODEL / f"{kind}.json"
