"""Several records, one parameter vector: which parameters are per record, and where.

The records of one rig share its physics but not everything (the drive gain ``g_v``
differs from record to record, the amplifier has an input offset ``v0``, V).  A
:class:`RecordLayout` says which parameters are per record and how:

``"shared"``
    One value for all records: meant for the input offset ``v0``, which is not a
    parameter of the single-record model (a model parameter is shared anyway when it is
    not listed).  When the records agree on their offset, a hierarchy of it has a
    population spread near zero, a funnel the ensemble sampler crosses slowly.
``"independent"``
    Each record ``r`` has its own value ``p[r]`` with the parameter's default prior.
``"hierarchical"``
    The values are drawn from a population, which is sampled too.  For a positive
    parameter (sampled in log, e.g. ``g_v``) the population is log-normal,
    ``log p[r] ~ N(log mu_p, tau_p^2)`` with ``tau_p`` the relative spread; for a signed
    one (``v0``) normal, ``p[r] ~ N(mu_p, tau_p^2)`` with ``tau_p`` in the parameter's
    unit.  ``mu_p`` gets the parameter's default prior and ``tau_p`` a half-normal prior
    (scale :data:`.record_priors.TAU_SCALE`).  This is the standard remedy when records
    disagree: a new record is predicted with a value drawn from the population, not with
    one record's.

Parameter vector: the shared model parameters in the model's order, then for every
per-record parameter (in layout order) ``mu_p, tau_p`` if hierarchical and ``p[r]`` for
every record, then the noise parameters (``sigma_j[r]``... when per record).

:func:`parameter_index` places the parameters in that vector, :func:`record_values` reads
one record's values back, and :func:`population_log_density` is the density of the
per-record values under their populations.  The likelihood
(:mod:`bayesmodal.inference.likelihood`) is built on them.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .._errors import ConfigError
from .record_scale import NOISE_SCALES, POWER_NAME

__all__ = [
    "RecordLayout",
    "parse_layout",
    "parameter_index",
    "record_values",
    "population_log_density",
    "PER_RECORD_KINDS",
    "DEFAULT_LAYOUT",
    "SIGNED",
]

PER_RECORD_KINDS = ("independent", "hierarchical", "shared")


def record_key(name: str) -> str:
    """A record name usable inside parameter names.

    Parameters
    ----------
    name : str
        The record's name (e.g. its file's stem).

    Returns
    -------
    str
        Letters, digits and ``_ - .`` only; ``"record"`` when nothing is left.
    """
    key = re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name)).strip("_")
    return key or "record"


@dataclass(frozen=True)
class RecordLayout:
    """Which parameters are per record, and how.

    Parameters
    ----------
    per_record : mapping of str to {"independent", "hierarchical", "shared"}
        Model parameter names (``g_v``, a mass, a damper, an extension parameter) or
        ``"v0"`` (the input offset, V), e.g. ``{"g_v": "hierarchical", "v0":
        "hierarchical"}``.  Empty: every parameter is shared, as in a single-record run.
    noise_per_record : bool
        Each record has its own noise parameters (default: shared).
    noise_scale : {"none", "response", "power"}
        ``"response"``: each record's noise level is the shared one times the relative
        size ``s_r`` of the model's response to its input
        (``bayesmodal.inference.record_scale``); ``"power"``: times ``s_r ** scale_power``
        with the exponent sampled in [0, 1]; ``"none"`` (default): one level in metres for
        every record.

    Examples
    --------
    >>> RecordLayout({"g_v": "hierarchical"}).kinds
    (('g_v', 'hierarchical'),)
    """

    per_record: Mapping[str, str] = field(default_factory=dict)
    noise_per_record: bool = False
    noise_scale: str = "none"

    def __post_init__(self) -> None:
        items = tuple((str(k), str(v)) for k, v in dict(self.per_record).items())
        for name, kind in items:
            if kind not in PER_RECORD_KINDS:
                raise ConfigError(
                    f"per-record parameter {name}: kind must be one of {PER_RECORD_KINDS}, "
                    f"got {kind!r}")
        object.__setattr__(self, "per_record", dict(items))
        object.__setattr__(self, "noise_per_record", bool(self.noise_per_record))
        if self.noise_scale not in NOISE_SCALES:
            raise ConfigError(f"noise_scale must be one of {NOISE_SCALES}, got "
                              f"{self.noise_scale!r}")

    @property
    def kinds(self) -> tuple[tuple[str, str], ...]:
        return tuple(self.per_record.items())

    def to_dict(self) -> dict:
        d = {"per_record": dict(self.per_record), "noise_per_record": self.noise_per_record}
        if self.noise_scale != "none":  # (absent at the default: earlier hashes stay valid)
            d["noise_scale"] = self.noise_scale
        return d

    @classmethod
    def from_dict(cls, d: Mapping) -> RecordLayout:
        return cls(dict(d.get("per_record", {})), bool(d.get("noise_per_record", False)),
                   str(d.get("noise_scale", "none")))


#: The package's default for several records: a drive gain per record drawn from a
#: population, and one input offset for all records (docs/uncertainty.md shows the
#: measurements behind it: the four ECP records agree on their offset, and a population of
#: offsets with a spread near zero made the sampler's autocorrelation time 1044 steps
#: against 52 with one shared offset).
DEFAULT_LAYOUT = RecordLayout({"g_v": "hierarchical", "v0": "shared"})


def parse_layout(text: str, *, noise_per_record: bool = False, noise_scale: str = "none"
                 ) -> RecordLayout:
    """A :class:`RecordLayout` from ``"g_v=hierarchical,v0=independent"`` (or ``"none"``).

    Examples
    --------
    >>> parse_layout("g_v=hierarchical").per_record
    {'g_v': 'hierarchical'}
    """
    text = str(text).strip()
    if text in ("", "none", "shared"):
        return RecordLayout({}, noise_per_record, noise_scale)
    per = {}
    for item in text.split(","):
        name, sep, kind = item.partition("=")
        if not sep or not name.strip():
            raise ConfigError(
                f"per-record item {item!r}: write NAME=KIND, e.g. g_v=hierarchical,v0=independent")
        per[name.strip()] = kind.strip()
    return RecordLayout(per, noise_per_record, noise_scale)


#: Signed per-record parameters (normal populations): the input offsets, V.
SIGNED = ("v0", "v_offset")


def _positive(name: str) -> bool:
    """Parameters sampled on a log scale when per record: the gain, masses, dampers and
    positive extension levels (everything but the input offsets)."""
    return name not in SIGNED


def model_layout(layout, mech: tuple[str, ...], extension) -> RecordLayout:
    """The layout of a likelihood of one model, checked against its parameters.

    Parameters
    ----------
    layout : RecordLayout or mapping
        The layout, or the keyword arguments of one.
    mech : tuple of str
        The single-record model parameters (linear, then the extension's).
    extension : Extension or None
        The model extension: with one, the input offset ``v0`` is the ``input_offset``
        effect's ``v_offset`` (one parameter, not two).

    Returns
    -------
    RecordLayout
    """
    layout = layout if isinstance(layout, RecordLayout) else RecordLayout(**dict(layout))
    for name, _ in layout.kinds:
        if name != "v0" and name not in mech:
            raise ConfigError(
                f"per-record parameter {name!r} is not a model parameter; choose from "
                f"{list(mech) + ['v0']}")
    if "v0" in layout.per_record and extension is not None:
        if "v_offset" not in mech:
            raise ConfigError(
                "an input offset per record (v0) with a model extension needs the "
                "input_offset effect: extensions = [..., 'input_offset']")
        # the effect's offset is the record's v0: one parameter, not two
        per = {("v_offset" if k == "v0" else k): v for k, v in layout.per_record.items()}
        layout = RecordLayout(per, layout.noise_per_record, layout.noise_scale)
    return layout


def parameter_index(layout: RecordLayout, mech: tuple[str, ...],
                    record_keys: tuple[str, ...], noise_names: tuple[str, ...]) -> dict:
    """Where each parameter sits in the parameter vector (the module docstring's order).

    Parameters
    ----------
    layout : RecordLayout
    mech : tuple of str
        The single-record model parameters (linear, then the extension's).
    record_keys : tuple of str
        The records' names as they appear in parameter names (:func:`record_key`).
    noise_names : tuple of str
        The noise model's parameter names for one record.

    Returns
    -------
    dict
        ``names`` (all parameters), ``mech``, ``shared`` and ``shared_pos`` (the shared
        model parameters' positions in ``mech`` and in the vector), ``groups`` (per
        per-record parameter: its ``kind``, the positions of its ``records`` and, when
        hierarchical, of ``mu`` and ``tau``), ``noise`` (each record's noise positions)
        and ``power`` (the sampled noise-scale exponent's position, or None).
    """
    names: list[str] = []
    per = layout.per_record
    shared = [nm for nm in mech if nm not in per]
    names += shared
    groups = {}
    for p, kind in layout.kinds:
        g = {"kind": kind}
        if kind == "hierarchical":
            g["mu"] = len(names)
            g["tau"] = len(names) + 1
            names += [f"mu_{p}", f"tau_{p}"]
        if kind == "shared":  # one value for every record (the input offset)
            g["records"] = [len(names)] * len(record_keys)
            names.append(p)
            groups[p] = g
            continue
        g["records"] = list(range(len(names), len(names) + len(record_keys)))
        names += [f"{p}[{k}]" for k in record_keys]
        groups[p] = g
    base_noise = noise_names
    if layout.noise_per_record:
        noise = [[len(names) + r * len(base_noise) + j for j in range(len(base_noise))]
                 for r in range(len(record_keys))]
        names += [f"{nm}[{k}]" for k in record_keys for nm in base_noise]
    else:
        noise = [list(range(len(names), len(names) + len(base_noise)))] * len(
            record_keys)
        names += list(base_noise)
    power = None
    if layout.noise_scale == "power":
        power = len(names)
        names.append(POWER_NAME)
    return {"names": tuple(names), "mech": mech, "power": power,
            "shared": [mech.index(nm) for nm in shared],
            "shared_pos": list(range(len(shared))), "groups": groups, "noise": noise}


def record_values(index: dict, theta: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray]:
    """Record ``r``'s single-record parameters and input offset (see
    ``Likelihood.record_theta``).

    Parameters
    ----------
    index : dict
        From :func:`parameter_index`.
    theta : ndarray, shape (nb, P)
    r : int
        The record.

    Returns
    -------
    full : ndarray, shape (nb, n_mech + n_noise)
    v0 : ndarray, shape (nb,)
        Input offset, V (zero when not per record).
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    ix = index
    nb = theta.shape[0]
    mech = np.empty((nb, len(ix["mech"])))
    mech[:, ix["shared"]] = theta[:, ix["shared_pos"]]
    v0 = np.zeros(nb)
    for p, g in ix["groups"].items():
        val = theta[:, g["records"][r]]
        if p == "v0":
            v0 = val
        else:
            mech[:, ix["mech"].index(p)] = val
    return np.concatenate([mech, theta[:, ix["noise"][r]]], axis=1), v0


def population_log_density(index: dict, theta: np.ndarray) -> np.ndarray:
    """Log density of the per-record values under their populations, shape (nb,) (see
    ``Likelihood.log_population``).

    Parameters
    ----------
    index : dict
        From :func:`parameter_index`.
    theta : ndarray, shape (nb, P)

    Returns
    -------
    ndarray, shape (nb,)
        ``-inf`` where not finite.
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    out = np.zeros(theta.shape[0])
    with np.errstate(all="ignore"):
        for p, g in index["groups"].items():
            if g["kind"] != "hierarchical":
                continue
            mu, tau = theta[:, g["mu"]], theta[:, g["tau"]]
            x = theta[:, g["records"]]
            if _positive(p):
                z = (np.log(x) - np.log(mu)[:, None]) / tau[:, None]
                dens = -0.5 * z**2 - np.log(tau)[:, None] - np.log(x)
            else:
                z = (x - mu[:, None]) / tau[:, None]
                dens = -0.5 * z**2 - np.log(tau)[:, None]
            out += np.sum(dens, axis=1) - 0.5 * x.shape[1] * np.log(2 * np.pi)
    return np.where(np.isfinite(out), out, -np.inf)
