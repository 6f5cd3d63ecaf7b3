"""Text shared by the evaluation reports."""

from __future__ import annotations


def split_use_line(use: dict | None) -> str:
    """One markdown line saying whether a report's split is held out: which models trained on which
    splits, and which calibration was measured on this one (from :func:`emogesture.checkpoints.split_use`)."""
    if not use:
        return ""
    trained = "; ".join(f"{name} on {'+'.join(splits)}" for name, splits in use["trained_on"].items())
    if use["held_out"]:
        return f"Split **{use['split']}: held out** (no part trained or calibrated on it). Trained: {trained}."
    return (f"Split **{use['split']}: not held out** — calibrated on it: {', '.join(use['calibrated_on_it'])} "
            f"(no weights trained on it). Trained: {trained}.")
