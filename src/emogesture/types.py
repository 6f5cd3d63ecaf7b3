"""Small data types passed between the layers."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

NUM_JOINTS = 55
FPS = 30
#: the eight emotions of BEAT2, in its label order
EMOTIONS: tuple[str, ...] = (
    "neutral", "happiness", "anger", "sadness", "contempt", "surprise", "fear", "disgust",
)
#: Apple's 52 ARKit face blendshapes (``ARFaceAnchor.BlendShapeLocation``), in the order Apple lists them
ARKIT_NAMES: tuple[str, ...] = (
    "eyeBlinkLeft", "eyeLookDownLeft", "eyeLookInLeft", "eyeLookOutLeft", "eyeLookUpLeft", "eyeSquintLeft",
    "eyeWideLeft", "eyeBlinkRight", "eyeLookDownRight", "eyeLookInRight", "eyeLookOutRight", "eyeLookUpRight",
    "eyeSquintRight", "eyeWideRight",
    "jawForward", "jawLeft", "jawRight", "jawOpen",
    "mouthClose", "mouthFunnel", "mouthPucker", "mouthLeft", "mouthRight", "mouthSmileLeft", "mouthSmileRight",
    "mouthFrownLeft", "mouthFrownRight", "mouthDimpleLeft", "mouthDimpleRight", "mouthStretchLeft",
    "mouthStretchRight", "mouthRollLower", "mouthRollUpper", "mouthShrugLower", "mouthShrugUpper",
    "mouthPressLeft", "mouthPressRight", "mouthLowerDownLeft", "mouthLowerDownRight", "mouthUpperUpLeft",
    "mouthUpperUpRight",
    "browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft", "browOuterUpRight",
    "cheekPuff", "cheekSquintLeft", "cheekSquintRight",
    "noseSneerLeft", "noseSneerRight",
    "tongueOut",
)


@dataclass
class SMPLXSequence:
    """An SMPL-X animation in the BEAT2 convention.

    Attributes:
        poses: ``[T, 55, 3]`` float32 axis-angle rotations, SMPL-X joint order (docs/design.md, 'Motion representation').
        trans: ``[T, 3]`` float32 root translation in metres (Y-up).
        betas: ``[B]`` float32 shape coefficients (BEAT2 stores 300).
        expressions: ``[T, E]`` float32 face expression coefficients (BEAT2 stores 100).
        arkit: ``[T, 52]`` float32 ARKit blendshape weights in ``[0, 1]`` (:data:`ARKIT_NAMES` order), or None
            when the sequence has no face track.
        fps: frames per second (30 for BEAT2).
        gender: body model gender, 'neutral' for BEAT2.
        model: body model name, 'smplx2020' for BEAT2.
    """

    poses: np.ndarray
    trans: np.ndarray
    betas: np.ndarray = field(default_factory=lambda: np.zeros(300, np.float32))
    expressions: np.ndarray | None = None
    fps: float = FPS
    gender: str = "neutral"
    model: str = "smplx2020"
    arkit: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.poses = np.asarray(self.poses, dtype=np.float32)
        if self.poses.ndim == 2 and self.poses.shape[1] == NUM_JOINTS * 3:
            self.poses = self.poses.reshape(-1, NUM_JOINTS, 3)
        if self.poses.ndim != 3 or self.poses.shape[1:] != (NUM_JOINTS, 3):
            raise ValueError(f"poses must be [T, 55, 3] or [T, 165], got {self.poses.shape}")
        t = self.poses.shape[0]
        self.trans = np.asarray(self.trans, dtype=np.float32)
        if self.trans.shape != (t, 3):
            raise ValueError(f"trans must be [{t}, 3], got {self.trans.shape}")
        self.betas = np.asarray(self.betas, dtype=np.float32).reshape(-1)
        if self.expressions is None:
            self.expressions = np.zeros((t, 100), np.float32)
        self.expressions = np.asarray(self.expressions, dtype=np.float32)
        if self.expressions.ndim != 2 or self.expressions.shape[0] != t:
            raise ValueError(f"expressions must be [{t}, E], got {self.expressions.shape}")
        if self.arkit is not None:
            self.arkit = np.asarray(self.arkit, dtype=np.float32)
            if self.arkit.shape != (t, len(ARKIT_NAMES)):
                raise ValueError(f"arkit must be [{t}, {len(ARKIT_NAMES)}], got {self.arkit.shape}")

    @property
    def num_frames(self) -> int:
        return int(self.poses.shape[0])

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.num_frames / float(self.fps)

    def slice(self, start: int, stop: int) -> "SMPLXSequence":
        """Frames ``start:stop`` as a new sequence (arrays copied)."""
        return SMPLXSequence(
            poses=self.poses[start:stop].copy(),
            trans=self.trans[start:stop].copy(),
            betas=self.betas.copy(),
            expressions=self.expressions[start:stop].copy(),
            fps=self.fps,
            gender=self.gender,
            model=self.model,
            arkit=None if self.arkit is None else self.arkit[start:stop].copy(),
        )
