"""Modal Assurance Criterion for EMA results (re-exports ``bayesmodal.modal.mac``).

``MAC_ij = |phi_a_i^H phi_b_j|^2 / ((phi_a_i^H phi_a_i) (phi_b_j^H phi_b_j))`` compares
two sets of shapes: 1 for shapes that are complex multiples of each other, 0 for
orthogonal ones.  ``mac`` takes shapes as columns; ``mac_estimates`` takes two
``ModalEstimate`` objects (whose shapes are rows).
"""

from __future__ import annotations

import numpy as np

from ..modal.mac import mac
from .result import ModalEstimate

__all__ = ["mac", "mac_estimates"]


def mac_estimates(a: ModalEstimate | np.ndarray, b: ModalEstimate | np.ndarray) -> np.ndarray:
    """MAC matrix between the mode shapes of two estimates.

    Parameters
    ----------
    a, b : ModalEstimate or ndarray, shape (n_modes, n_outputs)
        Estimates, or shapes as rows.

    Returns
    -------
    ndarray, shape (n_a, n_b)

    Examples
    --------
    >>> s = np.array([[1.0, 0.9, 0.6], [1.0, -0.5, -1.3]])
    >>> np.round(mac_estimates(s, 2 * s), 3)
    array([[1.   , 0.008],
           [0.008, 1.   ]])
    """
    sa = a.mode_shapes if isinstance(a, ModalEstimate) else np.asarray(a)
    sb = b.mode_shapes if isinstance(b, ModalEstimate) else np.asarray(b)
    return mac(np.atleast_2d(sa).T, np.atleast_2d(sb).T)
