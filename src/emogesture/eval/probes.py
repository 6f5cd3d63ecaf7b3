"""Linear probes: how much of a factor a latent space holds, as held-out classification accuracy."""

from __future__ import annotations

import numpy as np


def linear_probe_accuracy(train_x: np.ndarray, train_y: np.ndarray, test_x: np.ndarray, test_y: np.ndarray,
                          c: float = 1.0, max_iter: int = 2000) -> float:
    """Standardised multinomial logistic regression fit on ``train_x [N, D]`` -> accuracy on ``test_x [M, D]``.

    Test samples whose label never occurs in training are left out (a probe cannot name them).
    Deterministic (lbfgs, no random state involved).
    """
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    known = np.isin(test_y, np.unique(train_y))
    if known.sum() == 0 or len(np.unique(train_y)) < 2:
        return float("nan")
    clf = make_pipeline(StandardScaler(), LogisticRegression(C=c, max_iter=max_iter))
    clf.fit(train_x, train_y)
    return float((clf.predict(test_x[known]) == test_y[known]).mean())
