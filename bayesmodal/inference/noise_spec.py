"""The noise model of a run, from its text: one registry, one parser.

A run names its noise model as text (``[likelihood] noise = "ar4"``, ``bayesmodal sample
--noise ar4``, ``sample_posterior(..., noise="ar4")``).  :func:`parse_noise` reads that
text into a :class:`NoiseSpec` by the table :data:`NOISE_KINDS`, and
:meth:`NoiseSpec.model` builds the :class:`~bayesmodal.inference.noise.NoiseModel` that
the likelihood evaluates.  Every other module asks the spec (``spec.kind``,
``spec.one_record``, ``spec.name``) instead of comparing strings.

Adding a noise model is one module in ``bayesmodal/inference/noise/`` (a ``NoiseModel``
whose constructor takes no arguments) and one line in :data:`NOISE_KINDS`.

This module imports nothing of the package but its errors, so the lowest modules of
``inference`` (``priors``, ``likelihood``) and the run description can all use it; the
noise model classes are loaded by name when a spec builds one.
"""

from __future__ import annotations

import importlib
import re
from dataclasses import dataclass

from .._errors import ConfigError

__all__ = ["NOISE_KINDS", "NOISE_MODELS", "accepted_noise", "NoiseKind", "NoiseSpec", "parse_noise"]


@dataclass(frozen=True)
class NoiseKind:
    """One registry entry: how a noise model is written and which class builds it.

    Attributes
    ----------
    kind : str
        The spec's ``kind``; for models without parameters in their text also their
        canonical name (``"white"``, ``"ar:auto"``).
    pattern : str
        Regular expression the lower-case text without spaces must match in full.
    syntax : str
        How error messages show the accepted text.
    module : str or None
        Module of ``bayesmodal.inference.noise`` holding the class; None for a kind that is
        resolved from the data before a model exists (``"ar:auto"``).
    cls : str or None
        Name of the ``NoiseModel`` class in ``module``.
    one_record : bool
        White and AR(1) noise: the single-record likelihood evaluates them from
        sufficient statistics; every other kind goes through the several-record one.
    """

    kind: str
    pattern: str
    syntax: str
    module: str | None
    cls: str | None
    one_record: bool = False


#: The noise models, in the order error messages list them; the first full match wins
#: (``"ar1"`` is AR(1), not AR(p) with p = 1).
NOISE_KINDS: tuple[NoiseKind, ...] = (
    NoiseKind("white", r"white", "'white'", "base", "WhiteNoise", one_record=True),
    NoiseKind("ar1", r"ar1", "'ar1'", "base", "AR1Noise", one_record=True),
    NoiseKind("iar1", r"iar1", "'iar1' (AR(1) increments, a wandering error started at rest)",
              "integrated", "IntegratedAR1Noise"),
    NoiseKind("arp", r"ar(?P<order>\d+)|ar\((?P<orders>\d+(?:,\d+)*)\)",
              "'arP' (e.g. 'ar4', the same order on every output), 'ar(p1,...,pn)'",
              "arp", "ARpNoise"),
    NoiseKind("ar:auto", r"ar:auto",
              "'ar:auto' (order chosen by BIC on the least-squares residuals)", None, None),
    NoiseKind("ar1:motion", r"ar1:motion", "'ar1:motion' (AR(1) whose level follows each "
              "cart's measured speed)", "motion", "MotionAR1Noise"),
    NoiseKind("quantised", r"quantised", "'quantised' (readings rounded to the sensor's "
              "step: the interval-censored likelihood)", "quantised", "QuantisedNoise"),
    NoiseKind("process", r"process", "'process' (a random force on each cart, Kalman filter)",
              "kalman", "ProcessNoise"),
)

_BY_KIND = {k.kind: k for k in NOISE_KINDS}

#: Names of the noise models of the single-record likelihood (sufficient statistics).
NOISE_MODELS: tuple[str, ...] = tuple(sorted(k.kind for k in NOISE_KINDS if k.one_record))


def accepted_noise() -> str:
    """The noise models a run may name, as error messages and ``--help`` list them."""
    syn = [k.syntax for k in NOISE_KINDS]
    return ", ".join(syn[:-1]) + " or " + syn[-1]


@dataclass(frozen=True)
class NoiseSpec:
    """A noise model as named by a run, before the number of outputs is known.

    Attributes
    ----------
    kind : str
        A ``kind`` of :data:`NOISE_KINDS`: ``"white"``, ``"ar1"``, ``"iar1"``, ``"arp"``,
        ``"ar:auto"`` or ``"process"``.
    orders : tuple of int
        AR(p) only: the order of each output (``per_output``), or the one order of every
        output.
    per_output : bool
        AR(p) only: True for ``"ar(p1,...,pn)"``, False for ``"arP"``.

    Examples
    --------
    >>> parse_noise("AR(2, 3)")
    NoiseSpec(kind='arp', orders=(2, 3), per_output=True)
    >>> parse_noise("ar4").name, parse_noise("ar1").one_record
    ('ar4', True)
    """

    kind: str
    orders: tuple[int, ...] = ()
    per_output: bool = False

    @property
    def name(self) -> str:
        """The canonical text, which :func:`parse_noise` reads back to this spec."""
        if self.kind != "arp":
            return self.kind
        if self.per_output:
            return "ar(" + ",".join(str(p) for p in self.orders) + ")"
        # "ar1" is the AR(1) model; the same order 1 as AR(p) is only written with a zero
        p = self.orders[0]
        return f"ar{p:02d}" if p == 1 else f"ar{p}"

    @property
    def one_record(self) -> bool:
        """True for white and AR(1) noise (the single-record likelihood's two models)."""
        return _BY_KIND[self.kind].one_record

    def model(self, n_outputs: int):
        """The ``NoiseModel`` for records with ``n_outputs`` outputs.

        Parameters
        ----------
        n_outputs : int
            Outputs of the records; AR(p) orders given per output must match it.

        Returns
        -------
        NoiseModel

        Raises
        ------
        ConfigError
            For ``"ar:auto"``, whose orders come from a least-squares fit
            (``records.choose_noise``).
        DataError
            When ``"ar(p1,...,pn)"`` does not give one order per output.
        """
        entry = _BY_KIND[self.kind]
        if entry.module is None:
            raise ConfigError(
                f"noise model {self.name!r} is chosen from the residuals of a least-squares "
                "fit: resolve it with inference.records.choose_noise (sample_posterior and "
                "the runs do)")
        cls = getattr(importlib.import_module(f"{__package__}.noise.{entry.module}"),
                      entry.cls)
        if self.kind != "arp":
            return cls()
        orders = self.orders if self.per_output else self.orders * n_outputs
        model = cls(orders)
        model.names(n_outputs)  # one order per output, or DataError
        return model


def parse_noise(text) -> NoiseSpec:
    """Read the name of a noise model.

    Parameters
    ----------
    text : str or NoiseSpec
        ``"white"``, ``"ar1"``, ``"iar1"``, ``"arP"``, ``"ar(p1,...,pn)"``, ``"ar:auto"``
        or ``"process"``; case and spaces do not matter.  A spec is returned as it is.

    Returns
    -------
    NoiseSpec

    Raises
    ------
    ConfigError
        For any other text, listing what is accepted.

    Examples
    --------
    >>> parse_noise("ar:auto").kind
    'ar:auto'
    >>> parse_noise("ar(2,3,1)").orders
    (2, 3, 1)
    """
    if isinstance(text, NoiseSpec):
        return text
    canon = str(text).strip().lower().replace(" ", "")
    for entry in NOISE_KINDS:
        m = re.fullmatch(entry.pattern, canon)
        if m is None:
            continue
        if entry.kind != "arp":
            return NoiseSpec(entry.kind)
        if m.group("order") is not None:
            return NoiseSpec("arp", (int(m.group("order")),), per_output=False)
        return NoiseSpec("arp", tuple(int(x) for x in m.group("orders").split(",")),
                         per_output=True)
    raise ConfigError(f"noise model {text!r}: use {accepted_noise()}")
