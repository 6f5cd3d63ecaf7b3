"""Evaluation metrics (docs/design.md, 'Metrics'): FGD, Div, GA, BA, SRGR, jerk, and report figures.

Pure functions of numpy arrays; the feature extractor M and the audio onset detector live elsewhere and
hand their outputs (features, logits, onset times) to these functions.
"""

from emogesture.eval.classification import (
    classification_report,
    confusion_matrix,
    gesture_accuracy,
    predictions,
)
from emogesture.eval.metrics import (
    ARM_JOINTS,
    METRIC_CONSTANTS,
    UPPER_BODY_JOINTS,
    WRIST_JOINTS,
    beat_align,
    diversity,
    frechet_distance,
    frechet_from_stats,
    gaussian_stats,
    jerk,
    motion_beats,
    speed,
    srgr,
    wrist_jerk,
    wrist_speed,
)

__all__ = [
    "ARM_JOINTS",
    "METRIC_CONSTANTS",
    "UPPER_BODY_JOINTS",
    "WRIST_JOINTS",
    "beat_align",
    "classification_report",
    "confusion_matrix",
    "diversity",
    "frechet_distance",
    "frechet_from_stats",
    "gaussian_stats",
    "gesture_accuracy",
    "jerk",
    "motion_beats",
    "predictions",
    "speed",
    "srgr",
    "wrist_jerk",
    "wrist_speed",
]
