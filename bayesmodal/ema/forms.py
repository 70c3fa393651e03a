"""FRF forms of the sensor kinds: receptance, mobility, accelerance.

A position sensor measures the receptance ``G(jw)`` (m per input unit), a velocity sensor
the mobility ``jw G`` and an accelerometer the accelerance ``(jw)^2 G = -w^2 G``.  With
``G(jw) = sum_k [r_k / (jw - lambda_k) + conj]`` the form of order ``p`` is

    (jw)^p G(jw) = sum_k [lambda_k^p r_k / (jw - lambda_k) + conj] + (polynomial in jw)

so a fit of the measured form near its resonances reads the residue ``lambda^p r`` (in
the sensor's units times rad/s), and the receptance residue is that divided by
``lambda^p``.  Mode shapes from sensors of different kinds are only comparable after that
division (:func:`receptance_estimate`); with one kind the division is common to every
output of a mode and leaves the shapes as they were.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from .._errors import DataError
from .frf import FRF
from .result import ModalEstimate, normalise_shapes

__all__ = ["FRF_FORMS", "KIND_ORDERS", "form_units", "orders_of", "receptance_estimate",
           "to_receptance"]

#: Name of the FRF of each derivative order.
FRF_FORMS = {0: "receptance", 1: "mobility", 2: "accelerance"}

#: Derivative order of each sensor kind (``Sensor.kind``).
KIND_ORDERS = {"position": 0, "velocity": 1, "acceleration": 2}

_OUT_UNITS = {0: "m", 1: "m/s", 2: "m/s^2"}


def orders_of(kinds: Sequence[str]) -> np.ndarray:
    """Derivative order of each output from its sensor kind.

    Parameters
    ----------
    kinds : sequence of str
        ``"position"``, ``"velocity"`` or ``"acceleration"`` per output
        (``Rig.output_kinds``).

    Returns
    -------
    ndarray of int, shape (n_outputs,)
        0, 1 or 2.

    Examples
    --------
    >>> orders_of(["position", "acceleration"]).tolist()
    [0, 2]
    """
    try:
        return np.array([KIND_ORDERS[k] for k in kinds], dtype=int)
    except KeyError as exc:
        raise DataError(f"sensor kind {exc.args[0]!r} is not one of "
                        f"{tuple(KIND_ORDERS)}") from None


def form_units(order: int, input_kind: str = "voltage") -> str:
    """Units of an FRF of a derivative order per unit of input.

    Parameters
    ----------
    order : int
        0 receptance, 1 mobility, 2 accelerance.
    input_kind : {"voltage", "force"}
        The input (``Rig.input``): per V or per N.

    Returns
    -------
    str
        E.g. ``"m/s^2/N"`` for an accelerance per newton.

    Examples
    --------
    >>> form_units(2, "force")
    'm/s^2/N'
    """
    return f"{_OUT_UNITS[int(order)]}/{'N' if input_kind == 'force' else 'V'}"


def to_receptance(frf: FRF, orders: Sequence[int] | None = None) -> FRF:
    """The receptance of an FRF measured as mobility or accelerance: each output divided
    by ``(jw)^p``.

    Parameters
    ----------
    frf : FRF
    orders : sequence of int, optional
        Derivative order of each output (mixed sensors); default ``frf.derivative_order``
        for all.

    Returns
    -------
    FRF
        Same frequencies, coherence and averages; ``derivative_order`` 0.  At low
        frequencies the division amplifies an accelerometer's noise by ``1/w^2``.
    """
    p = (np.full(frf.n_outputs, frf.derivative_order) if orders is None
         else np.asarray(orders, dtype=int))
    if p.shape != (frf.n_outputs,):
        raise DataError(f"orders needs one entry per output ({frf.n_outputs}), got {p.shape}")
    jw = 1j * frf.omega_rad_s[:, None]
    units = frf.units
    for tail in ("/s^2/", "/s/"):
        units = units.replace(tail, "/")
    return replace(frf, H=frf.H / jw**p[None, :], derivative_order=0, units=units)


def receptance_estimate(est: ModalEstimate, orders: Sequence[int]) -> ModalEstimate:
    """A modal estimate with its residues in receptance units and the shapes renormalised.

    Parameters
    ----------
    est : ModalEstimate
        Residues fitted on each output's own form (order ``orders[i]``).
    orders : sequence of int, shape (n_outputs,)
        Derivative order of each output: the residue of output ``i`` is divided by
        ``lambda^orders[i]``.

    Returns
    -------
    ModalEstimate

    Examples
    --------
    >>> from bayesmodal.ema.result import modal_estimate
    >>> lam = -0.1 + 10j
    >>> est = modal_estimate("demo", [lam], [[1j, 2j * lam**2]])
    >>> receptance_estimate(est, [0, 2]).mode_shapes.real.round(12).tolist()
    [[1.0, 2.0]]
    """
    p = np.asarray(orders, dtype=int)
    if p.shape != (est.residues.shape[1],):
        raise DataError(f"orders needs one entry per output ({est.residues.shape[1]}), "
                        f"got {p.shape}")
    with np.errstate(divide="ignore", invalid="ignore"):
        R = est.residues / est.poles[:, None] ** p[None, :]
    shapes = normalise_shapes(R, est.reference) if R.size else R
    return replace(est, residues=R, mode_shapes=shapes)
