"""Goodness-of-fit measures."""

from __future__ import annotations

import numpy as np

__all__ = ["fit_percent"]


def fit_percent(y: np.ndarray, y_hat: np.ndarray) -> np.ndarray:
    """Fit percentage per output, ``100 (1 - ||y - y_hat|| / ||y - mean(y)||)``.

    This is MATLAB's ``compare``/``goodnessOfFit`` NRMSE fit, the "NRMSE" of the report's
    Table 5 (errata 5).  100 is a perfect fit, 0 is no better than the mean, and it can be
    negative.

    Parameters
    ----------
    y, y_hat : ndarray, shape (N, n_outputs) or (N,)

    Returns
    -------
    ndarray, shape (n_outputs,) (or a float for 1-D input), percent

    Examples
    --------
    >>> y = np.array([0.0, 1.0, 2.0])
    >>> float(fit_percent(y, y))
    100.0
    """
    y = np.asarray(y, dtype=float)
    y_hat = np.asarray(y_hat, dtype=float)
    if y.shape != y_hat.shape:
        raise ValueError(f"y and y_hat must have the same shape, got {y.shape} and {y_hat.shape}")
    num = np.linalg.norm(y - y_hat, axis=0)
    den = np.linalg.norm(y - y.mean(axis=0), axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = 100.0 * (1.0 - num / den)
    return out
