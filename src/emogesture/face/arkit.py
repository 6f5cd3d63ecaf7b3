"""Apple's 52 ARKit face blendshapes, and the face's poses in their terms.

The names (:data:`emogesture.types.ARKIT_NAMES`) are ARKit's ``ARFaceAnchor.BlendShapeLocation`` raw values, in
the order Apple's documentation lists them (eyes, jaw, mouth, brows, cheeks, nose, tongue); every weight lies
in ``[0, 1]``.

Two tables give the face's targets as sparse ``{name: weight}`` dictionaries:

- :data:`VISEME_SHAPES`: the mouth of each English phone (ARPAbet, as the CMU dictionary and pocketsphinx
  spell them), grouped by where the lips, teeth and jaw are. In ARKit ``mouthClose`` closes the lips over
  an open jaw, so a lip closure has ``mouthClose`` equal to its ``jawOpen``.
- :data:`EXPRESSIONS`: each emotion's expression at full intensity, after the action units of FACS
  (happiness: cheek raiser and lip-corner puller; sadness: inner brow raiser and lip-corner depressor; anger:
  brow lowerer, lid tightener and pressed lips; surprise: brows up, upper lids up, jaw drop; fear: brows up
  and drawn together, upper lids up, lips stretched; disgust: nose wrinkler and upper lip raiser; contempt:
  one lip corner tightened and raised).
"""

from __future__ import annotations

import numpy as np

from emogesture.types import ARKIT_NAMES

NUM_BLENDSHAPES = len(ARKIT_NAMES)
INDEX = {name: i for i, name in enumerate(ARKIT_NAMES)}


def both(name: str, weight: float) -> dict[str, float]:
    """``{nameLeft: weight, nameRight: weight}``."""
    return {f"{name}Left": weight, f"{name}Right": weight}


def vector(shape: dict[str, float]) -> np.ndarray:
    """A sparse ``{name: weight}`` -> ``[52]`` float32."""
    out = np.zeros(NUM_BLENDSHAPES, np.float32)
    for name, weight in shape.items():
        out[INDEX[name]] = weight
    return out


def _closed(jaw: float, **more: float) -> dict[str, float]:
    return {"jawOpen": jaw, "mouthClose": jaw, **more}


#: the viseme groups: the phones that share a mouth, and that mouth
VISEME_GROUPS: dict[str, tuple[tuple[str, ...], dict[str, float]]] = {
    "rest": (("SIL", "+NSN+", "+SPN+", "+BREATH+", "+COUGH+", "+LAUGH+", "+SMACK+", "+UM+", "+UH+"), {}),
    "lips": (("P", "B", "M"), _closed(0.06, **both("mouthPress", 0.35))),
    "teeth_lip": (("F", "V"), {"jawOpen": 0.08, "mouthRollLower": 0.55, **both("mouthUpperUp", 0.2)}),
    "tongue_teeth": (("TH", "DH"), {"jawOpen": 0.14, "tongueOut": 0.25}),
    "tongue_ridge": (("T", "D", "N", "L"), {"jawOpen": 0.14, **both("mouthStretch", 0.12)}),
    "hiss": (("S", "Z"), {"jawOpen": 0.07, **both("mouthStretch", 0.3)}),
    "hush": (("SH", "ZH", "CH", "JH"), {"jawOpen": 0.1, "mouthFunnel": 0.5, "mouthPucker": 0.25}),
    "back": (("K", "G", "NG", "HH"), {"jawOpen": 0.22}),
    "r": (("R", "ER"), {"jawOpen": 0.18, "mouthFunnel": 0.3, "mouthPucker": 0.35}),
    "w": (("W",), {"jawOpen": 0.08, "mouthPucker": 0.8, "mouthFunnel": 0.3}),
    "y": (("Y",), {"jawOpen": 0.12, **both("mouthStretch", 0.3)}),
    "open": (("AA", "AH", "AY", "AW"), {"jawOpen": 0.58, **both("mouthLowerDown", 0.2)}),
    "open_wide": (("AE",), {"jawOpen": 0.5, **both("mouthStretch", 0.3), **both("mouthLowerDown", 0.2)}),
    "open_round": (("AO", "OY"), {"jawOpen": 0.5, "mouthFunnel": 0.45}),
    "mid": (("EH", "EY"), {"jawOpen": 0.34, **both("mouthStretch", 0.28)}),
    "close_front": (("IH", "IY"), {"jawOpen": 0.2, **both("mouthStretch", 0.4), **both("mouthSmile", 0.1)}),
    "round": (("OW",), {"jawOpen": 0.34, "mouthFunnel": 0.5, "mouthPucker": 0.3}),
    "close_round": (("UH", "UW"), {"jawOpen": 0.16, "mouthPucker": 0.7, "mouthFunnel": 0.3}),
}
#: phone -> its viseme group's name
VISEME_OF = {phone: group for group, (phones, _) in VISEME_GROUPS.items() for phone in phones}
#: viseme group -> its mouth ``[52]``
VISEME_SHAPES = {group: vector(shape) for group, (_, shape) in VISEME_GROUPS.items()}
#: the phones whose lips meet (the checks' bilabials), and the open vowels
CLOSURES = VISEME_GROUPS["lips"][0]
OPEN_VOWELS = ("AA", "AE", "AH", "AO", "AW", "AY")

#: each emotion's expression at full intensity (neutral: none); emogesture.types.EMOTIONS order
EXPRESSIONS: dict[str, dict[str, float]] = {
    "neutral": {},
    "happiness": {**both("cheekSquint", 0.55), **both("mouthSmile", 0.7), **both("eyeSquint", 0.3),
                  **both("mouthDimple", 0.2)},
    "anger": {**both("browDown", 0.8), **both("eyeSquint", 0.45), **both("mouthPress", 0.45),
              **both("noseSneer", 0.25)},
    "sadness": {"browInnerUp": 0.75, **both("mouthFrown", 0.55), "mouthShrugLower": 0.3,
                **both("eyeLookDown", 0.15), **both("browDown", 0.1)},
    "contempt": {"mouthSmileLeft": 0.45, "mouthDimpleLeft": 0.4, "mouthPressLeft": 0.2, "noseSneerLeft": 0.1,
                 "eyeSquintLeft": 0.15},
    "surprise": {"browInnerUp": 0.65, **both("browOuterUp", 0.75), **both("eyeWide", 0.65), "jawOpen": 0.18},
    "fear": {"browInnerUp": 0.8, **both("browOuterUp", 0.35), **both("eyeWide", 0.6), **both("mouthStretch", 0.45),
             **both("browDown", 0.15)},
    "disgust": {**both("noseSneer", 0.7), **both("mouthUpperUp", 0.45), **both("browDown", 0.35),
                **both("cheekSquint", 0.3), "mouthShrugUpper": 0.25},
}
