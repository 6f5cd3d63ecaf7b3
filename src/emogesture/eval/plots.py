"""Figures for evaluation reports (matplotlib's Agg canvas, imported inside the function)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np


def save_confusion_matrix(cm: np.ndarray, labels: Sequence[str], path: str | os.PathLike[str],
                          title: str = "", overwrite: bool = False, dpi: int = 120) -> Path:
    """Write a row-normalised, annotated confusion matrix ``cm`` ``[C, C]`` (rows true) as a PNG.

    Each cell shows the row fraction (and the raw count below it); rows without samples stay empty.
    The file is written to a temporary file in the target directory and renamed into place, so a
    reader never sees a partial PNG. Raises ``FileExistsError`` if ``path`` exists and ``overwrite``
    is false. Returns the path written.
    """
    # Agg canvas attached explicitly to a pyplot-free Figure: no global backend switch, no display needed.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    counts = np.asarray(cm, dtype=np.float64)
    if counts.ndim != 2 or counts.shape[0] != counts.shape[1]:
        raise ValueError(f"cm must be [C, C], got shape {counts.shape}")
    c = counts.shape[0]
    if len(labels) != c:
        raise ValueError(f"{len(labels)} labels for a {c}x{c} matrix")
    out = Path(path)
    if out.exists() and not overwrite:
        raise FileExistsError(f"{out}: exists (pass overwrite=True to replace it)")
    out.parent.mkdir(parents=True, exist_ok=True)

    rows = counts.sum(axis=1, keepdims=True)
    frac = np.divide(counts, rows, out=np.zeros_like(counts), where=rows > 0)
    size = max(4.0, 0.6 * c + 2.0)
    fig = Figure(figsize=(size, size))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    im = ax.imshow(frac, cmap="Blues", vmin=0.0, vmax=1.0)
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    ax.set_xticks(range(c), labels=list(labels), rotation=45, ha="right")
    ax.set_yticks(range(c), labels=list(labels))
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    if title:
        ax.set_title(title)
    for i in range(c):
        if rows[i, 0] == 0:
            continue
        for j in range(c):
            colour = "white" if frac[i, j] > 0.5 else "black"
            ax.text(j, i, f"{frac[i, j]:.2f}\n{int(counts[i, j])}", ha="center", va="center",
                    color=colour, fontsize=7)
    fig.tight_layout()

    fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fig.savefig(fh, format="png", dpi=dpi)
        if not overwrite and out.exists():
            raise FileExistsError(f"{out}: exists (pass overwrite=True to replace it)")
        os.replace(tmp, out)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return out
