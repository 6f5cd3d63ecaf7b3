"""Classification scores shared by GA (gesture emotion accuracy) and the speech model's EA/EF1/SA/SF1.

Pure numpy; labels are integer class indices in ``[0, num_classes)``.
"""

from __future__ import annotations

import numpy as np


def _as_labels(y: np.ndarray, name: str, num_classes: int | None = None) -> np.ndarray:
    a = np.asarray(y).reshape(-1)
    if a.size and not np.issubdtype(a.dtype, np.integer):
        if not np.all(np.equal(np.mod(a, 1), 0)):
            raise ValueError(f"{name} must hold integer class indices")
    a = a.astype(np.int64)
    if num_classes is not None and a.size and (a.min() < 0 or a.max() >= num_classes):
        raise ValueError(f"{name} has labels outside [0, {num_classes}): min {a.min()}, max {a.max()}")
    return a


def predictions(logits_or_pred: np.ndarray) -> np.ndarray:
    """Top-1 predictions ``[N]`` from logits/probabilities ``[N, C]`` (argmax) or predictions ``[N]``."""
    x = np.asarray(logits_or_pred)
    if x.ndim == 2:
        return np.argmax(x, axis=1).astype(np.int64)
    if x.ndim == 1:
        return _as_labels(x, "predictions")
    raise ValueError(f"expected logits [N, C] or predictions [N], got shape {x.shape}")


def confusion_matrix(y_true: np.ndarray, y_pred: np.ndarray, num_classes: int) -> np.ndarray:
    """Counts ``[C, C]`` (int64): row = true class, column = predicted class."""
    t = _as_labels(y_true, "y_true", num_classes)
    p = _as_labels(y_pred, "y_pred", num_classes)
    if t.shape != p.shape:
        raise ValueError(f"y_true {t.shape} and y_pred {p.shape} differ in length")
    cm = np.zeros((num_classes, num_classes), dtype=np.int64)
    np.add.at(cm, (t, p), 1)
    return cm


def classification_report(y_true: np.ndarray, y_pred: np.ndarray, num_classes: int) -> dict:
    """Accuracy, macro-F1 and per-class scores of labels ``y_true`` ``[N]`` vs ``y_pred`` ``[N]``.

    Returns a dict with
    ``accuracy`` (fraction correct), ``macro_f1``, ``confusion`` (``[C, C]`` int64 counts, rows true,
    columns predicted), ``precision``/``recall``/``f1`` (``[C]`` float, ``nan`` where undefined),
    ``support`` (``[C]`` true counts), ``present`` (``[C]`` bool) and ``num_samples``.

    Per class ``F1 = 2 TP / (2 TP + FP + FN)``. A class absent from both ``y_true`` and ``y_pred``
    (``TP + FP + FN = 0``) has ``nan`` F1 and is excluded from the macro average; a class that occurs on
    only one side has F1 = 0 and is included. This equals scikit-learn's
    ``f1_score(average="macro", labels=<classes present in y_true or y_pred>)``.
    ``precision`` is ``nan`` for never-predicted classes, ``recall`` for classes absent from ``y_true``.
    Raises ``ValueError`` for empty input.
    """
    cm = confusion_matrix(y_true, y_pred, num_classes)
    n = int(cm.sum())
    if n == 0:
        raise ValueError("classification_report needs at least one sample")
    tp = np.diag(cm).astype(np.float64)
    pred_count = cm.sum(axis=0).astype(np.float64)
    true_count = cm.sum(axis=1).astype(np.float64)
    fp, fn = pred_count - tp, true_count - tp
    present = (tp + fp + fn) > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        precision = np.where(pred_count > 0, tp / pred_count, np.nan)
        recall = np.where(true_count > 0, tp / true_count, np.nan)
        f1 = np.where(present, 2 * tp / (2 * tp + fp + fn), np.nan)
    return {
        "accuracy": float(tp.sum() / n),
        "macro_f1": float(np.mean(f1[present])),
        "confusion": cm,
        "precision": precision,
        "recall": recall,
        "f1": f1,
        "support": true_count.astype(np.int64),
        "present": present,
        "num_samples": n,
    }


def gesture_accuracy(logits_or_pred: np.ndarray, labels: np.ndarray) -> float:
    """GA: top-1 accuracy of logits ``[N, C]`` (argmax) or predicted labels ``[N]`` against ``labels`` ``[N]``.

    For emotion edits, ``labels`` are the emotion-audio's labels (edit GA in docs/design.md, 'Metrics').
    Raises ``ValueError`` for empty input or a length mismatch.
    """
    pred = predictions(logits_or_pred)
    true = _as_labels(labels, "labels")
    if pred.shape != true.shape:
        raise ValueError(f"predictions {pred.shape} and labels {true.shape} differ in length")
    if true.size == 0:
        raise ValueError("gesture_accuracy needs at least one sample")
    return float(np.mean(pred == true))
