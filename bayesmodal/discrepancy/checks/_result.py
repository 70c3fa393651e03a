"""The result every residual diagnostic returns."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

__all__ = ["Diagnostic"]


@dataclass(frozen=True)
class Diagnostic:
    """Outcome of one residual diagnostic.

    Attributes
    ----------
    name : str
        Diagnostic family, e.g. ``"whiteness"``, ``"friction_signature"``.
    statistic : float
        The test statistic (its meaning is given in ``summary`` and the function's
        docstring).
    p_value : float or None
        Family-wise p-value (Bonferroni over outputs or modes) when the diagnostic is a
        significance test, else None.
    threshold : float or None
        Decision threshold on ``statistic`` when the diagnostic is not a significance test
        (``alpha`` is used instead when ``p_value`` is given).
    detected : bool
        True when the residuals show the effect: ``p_value < alpha`` or ``statistic``
        beyond ``threshold`` (and the effect-size guard, where documented).
    suggests : tuple of str
        Model extensions (keys of ``bayesmodal.model.effects.EXTENSIONS``) or other causes
        (``"unmodelled_mode"``, ``"sensor_gain"``, ``"input_gain"``) the evidence points to
        when detected; empty otherwise.
    location : str or None
        Where the effect shows most, e.g. ``"cart 2"`` or ``"output 1"``.
    summary : str
        One line for people.
    detail : Mapping
        Per-output numbers and the arrays the plot functions draw (read-only mapping).
    """

    name: str
    statistic: float
    p_value: float | None
    threshold: float | None
    detected: bool
    suggests: tuple[str, ...]
    location: str | None
    summary: str
    detail: Mapping[str, Any] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "detail", MappingProxyType(dict(self.detail)))
        object.__setattr__(self, "suggests", tuple(self.suggests))
