"""emogesture: speech to emotional 3D body gestures (SMPL-X), after AMUSE (CVPR 2024).

Data flows one way:
audio -> fbank -> audio latents -> diffusion in motion-latent space -> motion features
-> SMPL-X sequence -> files.
"""

from typing import TYPE_CHECKING

from emogesture.version import __version__

#: the public API, imported when first used (``import emogesture`` stays light):
#: ``from emogesture import animate, AnimationRequest, GesturePipeline, GenerationConfig``
_PUBLIC = {"animate": "emogesture.pipeline.animate", "AnimationRequest": "emogesture.pipeline.animate",
           "AnimationResult": "emogesture.pipeline.animate", "GesturePipeline": "emogesture.pipeline.generate",
           "GenerationConfig": "emogesture.models.generation", "SMPLXSequence": "emogesture.types"}
__all__ = ["__version__", *_PUBLIC]

if TYPE_CHECKING:
    from emogesture.models.generation import GenerationConfig
    from emogesture.pipeline.animate import AnimationRequest, AnimationResult, animate
    from emogesture.pipeline.generate import GesturePipeline
    from emogesture.types import SMPLXSequence


def __getattr__(name: str):
    if name not in _PUBLIC:
        raise AttributeError(f"module 'emogesture' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(_PUBLIC[name]), name)
    globals()[name] = value
    return value
