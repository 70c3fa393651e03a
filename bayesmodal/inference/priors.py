"""Prior distributions and the transformed sampling space.

Every parameter has a prior density ``p(theta_i)`` in physical units and a bijective
transform ``theta_i = f_i(z_i)`` to an unbounded (or half-bounded) sampling coordinate:

- ``"log"`` for strictly positive parameters (g_v, masses, ca, sigma):
  ``theta = exp(z)``, ``log |f'(z)| = z``;
- ``"tanh"`` for the AR(1) coefficient ``phi`` in (-1, 1): ``phi = tanh(z)``,
  ``log |f'(z)| = log(1 - phi^2)``;
- ``"identity"`` for parameters whose posterior may sit on a zero bound (every damper of
  the free model and the stiffness-proportional cb): a log transform would send
  ``z -> -inf`` for a damper that is not there, and the walkers would need ever longer to
  come back.

The sampler works with the density of ``z``::

    log p_z(z) = sum_i [ log p_i(f_i(z_i)) + log |f_i'(z_i)| ],

so that the draws of ``theta = f(z)`` follow the prior (and posterior) stated in physical
units.  Only the change of variables is added; the prior itself is never re-stated in z.

Defaults (SI units):

=============  ====================================  ==========
parameter      prior                                 transform
=============  ====================================  ==========
g_v            Uniform(1, 15) N/V                    log
m1..mn         Uniform(0.2, 5) kg                    log
c1..cn         Uniform(0, 20) N s/m                  identity
c12, c23, ...  Uniform(0, 20) N s/m                  identity
ca             Uniform(0, 20) 1/s                    log
cb             Uniform(0, 0.01) s                    identity
sigma_k        LogUniform(1e-7, 0.1) m               log
phi_k          Uniform(-1, 1)                        tanh
=============  ====================================  ==========

A velocity sensor's ``sigma_k`` is LogUniform(1e-7, 1) m/s, an accelerometer's
LogUniform(1e-5, 100) m/s^2 (``SIGMA_PRIOR_BOUNDS``).  A rig with a force input has no
``g_v``: the input is in newtons.

Model extensions (``default_priors(..., extension=...)``) add their own parameters after the
linear ones, each with ``Uniform(lo, hi)`` on its ``ParamSpec.bounds``, e.g.

=============  ====================================  ==========
Fc1..Fcn       Uniform(0, 2) N                       identity
Fs1..Fsn       Uniform(0, 3) N (and Fs_i >= Fc_i)    identity
tau_s          Uniform(0, 0.05) s                    identity
delay_s        Uniform(0, 0.03) s                    identity
gap_m          Uniform(0, 1e-3) m                    identity
m_p            Uniform(0.05, 0.5) kg                 log
k3_1..k3_n     Uniform(-2e5, 2e5) N/m^3              identity
v_sat          Uniform(0.5, 10) V                    log
=============  ====================================  ==========

The transform follows the same rule as for the dampers: ``identity`` when the prior
reaches down to zero (or below), because the effect may be absent and its posterior then
sits on the zero bound; ``log`` for a strictly positive range.  Joint constraints of an
extension (``Fs_i >= Fc_i``, ``m_p < m1``) are not part of these independent priors: the
likelihood is ``-inf`` where they fail, so the prior in effect is the box restricted to
the admissible set (for the nested-sampling evidence this is the box prior with zero
likelihood outside the admissible set).

``sigma_k`` is the white-noise standard deviation of output ``k`` or, for AR(1) noise, the
standard deviation of the innovations.  ``ca`` up to 20 1/s covers a mass-proportional
damping ratio ``ca / (2 omega)`` of 1 at 10 rad/s; ``cb`` up to 0.01 s covers a stiffness-
proportional ratio ``cb omega / 2`` of 0.2 at the highest mode (about 42 rad/s).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError
from ..model.effects import resolve_extension
from ..model.system import param_kinds
from .noise_spec import NOISE_MODELS, parse_noise

__all__ = [
    "Uniform",
    "LogUniform",
    "Normal",
    "PriorSet",
    "TRANSFORMS",
    "default_priors",
    "noise_names",
    "SIGMA_PRIOR_BOUNDS",
]

#: Transforms from the sampling coordinate z to the physical parameter.
TRANSFORMS = ("identity", "log", "tanh")

_LOG_2PI = float(np.log(2 * np.pi))


# The densities, elementwise: a prior's ``logpdf`` calls them with its scalars, ``PriorSet``
# with the stacked parameters of all priors of one kind (the same operations, bit for bit).
def _uniform_logpdf(x, lo, hi):
    inside = (x >= lo) & (x <= hi)
    return np.where(inside, -np.log(hi - lo), -np.inf)


def _loguniform_logpdf(x, lo, hi):
    inside = (x >= lo) & (x <= hi)
    with np.errstate(divide="ignore", invalid="ignore"):
        # log(hi) - log(lo), not log(hi / lo): the ratio overflows for wide priors
        val = -np.log(x) - np.log(np.log(hi) - np.log(lo))
    return np.where(inside, val, -np.inf)


def _normal_logpdf(x, mu, sd, lo, hi, log_mass):
    val = -0.5 * ((x - mu) / sd) ** 2 - np.log(sd) - 0.5 * _LOG_2PI
    val = val - log_mass
    return np.where((x >= lo) & (x <= hi), val, -np.inf)


@dataclass(frozen=True)
class Uniform:
    """Uniform prior on ``[lo, hi]``.

    Parameters
    ----------
    lo, hi : float
        Bounds, in the parameter's unit; ``lo < hi``.
    """

    lo: float
    hi: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.lo) and np.isfinite(self.hi) and self.lo < self.hi):
            raise ConfigError(f"Uniform prior needs finite lo < hi, got ({self.lo}, {self.hi})")

    @property
    def support(self) -> tuple[float, float]:
        return (float(self.lo), float(self.hi))

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        return _uniform_logpdf(np.asarray(x, dtype=float), self.lo, self.hi)

    def _columns(self) -> tuple[float, ...]:
        return (self.lo, self.hi)

    _batch = staticmethod(_uniform_logpdf)

    def ppf(self, u: np.ndarray) -> np.ndarray:
        """Quantile function (used as the nested-sampling prior transform)."""
        return self.lo + np.asarray(u, dtype=float) * (self.hi - self.lo)


@dataclass(frozen=True)
class LogUniform:
    """Log-uniform (Jeffreys) prior, density proportional to ``1/x`` on ``[lo, hi]``, lo > 0."""

    lo: float
    hi: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.lo) and np.isfinite(self.hi) and 0 < self.lo < self.hi):
            raise ConfigError(
                f"LogUniform prior needs finite 0 < lo < hi, got ({self.lo}, {self.hi})"
            )

    @property
    def support(self) -> tuple[float, float]:
        return (float(self.lo), float(self.hi))

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        return _loguniform_logpdf(np.asarray(x, dtype=float), self.lo, self.hi)

    def _columns(self) -> tuple[float, ...]:
        return (self.lo, self.hi)

    _batch = staticmethod(_loguniform_logpdf)

    def ppf(self, u: np.ndarray) -> np.ndarray:
        log_lo, log_hi = np.log(self.lo), np.log(self.hi)
        return np.exp(log_lo + (log_hi - log_lo) * np.asarray(u, dtype=float))


@dataclass(frozen=True)
class Normal:
    """Gaussian prior ``N(mu, sd^2)``, optionally truncated to ``[lo, hi]``.

    The truncated density is renormalised, so evidences stay correct.
    """

    mu: float
    sd: float
    lo: float = -np.inf
    hi: float = np.inf

    def __post_init__(self) -> None:
        if not (np.isfinite(self.mu) and np.isfinite(self.sd) and self.sd > 0):
            raise ConfigError(
                f"Normal prior needs finite mu and sd > 0, got ({self.mu}, {self.sd})"
            )
        if not self.lo < self.hi:
            raise ConfigError(f"Normal prior needs lo < hi, got ({self.lo}, {self.hi})")

    @property
    def support(self) -> tuple[float, float]:
        return (float(self.lo), float(self.hi))

    def _mass(self) -> float:
        from scipy.stats import norm

        return float(norm.cdf(self.hi, self.mu, self.sd) - norm.cdf(self.lo, self.mu, self.sd))

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        return _normal_logpdf(np.asarray(x, dtype=float), *self._columns())

    def _columns(self) -> tuple[float, ...]:
        return (self.mu, self.sd, self.lo, self.hi, np.log(self._mass()))

    _batch = staticmethod(_normal_logpdf)

    def ppf(self, u: np.ndarray) -> np.ndarray:
        from scipy.stats import norm

        a = norm.cdf(self.lo, self.mu, self.sd)
        b = norm.cdf(self.hi, self.mu, self.sd)
        return norm.ppf(a + np.asarray(u, dtype=float) * (b - a), self.mu, self.sd)


#: Bounds of the LogUniform prior of a sensor's noise level, by sensor kind, SI (m, m/s,
#: m/s^2): from below an encoder count to a centimetre, and the same spans for the
#: velocity and acceleration sensors of lab rigs (a MEMS accelerometer's noise is
#: 1e-3..1e-1 m/s^2).
SIGMA_PRIOR_BOUNDS = {"position": (1e-7, 0.1), "velocity": (1e-7, 1.0),
                      "acceleration": (1e-5, 100.0)}


def noise_names(n_outputs: int, noise: str) -> tuple[str, ...]:
    """Names of the noise parameters of the single-record likelihood's models: white,
    ``sigma_1..n``, and AR(1), ``sigma_1..n`` then ``phi_1..n`` (the noise model's own
    ``names``).

    Parameters
    ----------
    n_outputs : int
        Outputs of the records (one ``sigma`` each, and one ``phi`` each for AR(1)).
    noise : {"white", "ar1"}
        The noise model.

    Returns
    -------
    tuple of str

    Examples
    --------
    >>> noise_names(2, "ar1")
    ('sigma_1', 'sigma_2', 'phi_1', 'phi_2')
    """
    if noise not in NOISE_MODELS:
        raise ConfigError(f"noise must be 'ar1' or 'white', got {noise!r}")
    return parse_noise(noise).model(n_outputs).names(n_outputs)


@dataclass(frozen=True)
class PriorSet:
    """Joint (independent) prior over named parameters, with its sampling transforms.

    Parameters
    ----------
    names : tuple of str, length P
        Parameter names in vector order.
    priors : tuple of prior objects, length P
        Each with ``logpdf``, ``ppf`` and ``support``.
    transforms : tuple of str, length P
        One of ``TRANSFORMS`` per parameter.

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> ps = default_priors(LinearModel(Rig(), "proportional"), noise="white")
    >>> ps.names[-3:]
    ('sigma_1', 'sigma_2', 'sigma_3')
    """

    names: tuple[str, ...]
    priors: tuple
    transforms: tuple[str, ...]

    def __post_init__(self) -> None:
        if not (len(self.names) == len(self.priors) == len(self.transforms)):
            raise ConfigError("names, priors and transforms must have the same length")
        if len(set(self.names)) != len(self.names):
            raise ConfigError(f"duplicated parameter names {self.names}")
        for name, prior, tr in zip(self.names, self.priors, self.transforms, strict=True):
            if tr not in TRANSFORMS:
                raise ConfigError(f"{name}: unknown transform {tr!r}; use one of {TRANSFORMS}")
            lo, hi = prior.support
            if tr == "log" and lo < 0:
                raise ConfigError(f"{name}: a log transform needs a prior on x >= 0, got {prior}")
            if tr == "tanh" and (lo < -1 or hi > 1):
                raise ConfigError(f"{name}: a tanh transform needs a prior inside [-1, 1]")
        object.__setattr__(self, "_log", np.array([t == "log" for t in self.transforms]))
        object.__setattr__(self, "_tanh", np.array([t == "tanh" for t in self.transforms]))
        # one batched density call per kind of prior (log_prior runs once per emcee half-step)
        groups = []
        for kind in dict.fromkeys(type(p) for p in self.priors):
            idx = np.array([i for i, p in enumerate(self.priors) if type(p) is kind])
            cols = np.array([self.priors[i]._columns() for i in idx], dtype=float).T
            groups.append((kind._batch, idx, tuple(cols)))
        object.__setattr__(self, "_groups", tuple(groups))

    @property
    def n_params(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise ConfigError(f"unknown parameter {name!r}; known: {self.names}") from None

    def replace(self, overrides: Mapping[str, object]) -> PriorSet:
        """A copy with some priors replaced, ``{name: prior}``; unknown names are rejected."""
        priors = list(self.priors)
        for name, prior in overrides.items():
            priors[self.index(name)] = prior
        return PriorSet(self.names, tuple(priors), self.transforms)

    # ---------------------------------------------------------------- transforms
    def to_physical(self, z: np.ndarray) -> np.ndarray:
        """Physical parameters ``theta = f(z)``, shape (..., P)."""
        z = np.asarray(z, dtype=float)
        th = z.copy()
        with np.errstate(over="ignore"):
            th[..., self._log] = np.exp(z[..., self._log])
        th[..., self._tanh] = np.tanh(z[..., self._tanh])
        return th

    def to_sampling(self, theta: np.ndarray) -> np.ndarray:
        """Sampling coordinates ``z = f^-1(theta)``, shape (..., P)."""
        theta = np.asarray(theta, dtype=float)
        z = theta.copy()
        with np.errstate(divide="ignore", invalid="ignore"):
            z[..., self._log] = np.log(theta[..., self._log])
            z[..., self._tanh] = np.arctanh(theta[..., self._tanh])
        return z

    def log_jacobian(self, z: np.ndarray) -> np.ndarray:
        """``sum_i log |d theta_i / d z_i|``, shape (...,)."""
        z = np.asarray(z, dtype=float)
        out = np.sum(z[..., self._log], axis=-1)
        # log(1 - tanh^2 z) = log(4) - 2 |z| - 2 log(1 + exp(-2 |z|)), stable for large |z|
        a = np.abs(z[..., self._tanh])
        out = out + np.sum(np.log(4.0) - 2 * a - 2 * np.log1p(np.exp(-2 * a)), axis=-1)
        return out

    # ---------------------------------------------------------------- densities
    def log_prior(self, theta: np.ndarray) -> np.ndarray:
        """Log prior density in physical units, shape (...,); ``-inf`` outside the support."""
        theta = np.asarray(theta, dtype=float)
        vals = np.empty(theta.shape)
        for logpdf, idx, cols in self._groups:
            vals[..., idx] = logpdf(theta[..., idx], *cols)
        out = np.zeros(theta.shape[:-1])
        for i in range(theta.shape[-1]):  # in parameter order, as the sum always was
            out = out + vals[..., i]
        return np.where(np.isnan(out), -np.inf, out)

    def log_prior_z(self, z: np.ndarray, theta: np.ndarray | None = None) -> np.ndarray:
        """Log density of the sampling coordinates, ``log p(f(z)) + log |f'(z)|``.

        ``theta``, when given, must be ``to_physical(z)`` (a caller that needs it anyway
        saves the second transform).
        """
        z = np.asarray(z, dtype=float)
        lp = self.log_prior(self.to_physical(z) if theta is None else theta)
        with np.errstate(invalid="ignore", over="ignore"):  # wild walkers: -inf below
            out = lp + self.log_jacobian(z)
        return np.where(np.isfinite(lp), out, -np.inf)

    def prior_transform(self, u: np.ndarray) -> np.ndarray:
        """Map the unit cube to physical parameters (the nested-sampling prior transform).

        Parameters
        ----------
        u : ndarray, shape (..., P), values in [0, 1]
        """
        u = np.asarray(u, dtype=float)
        return np.stack([p.ppf(u[..., i]) for i, p in enumerate(self.priors)], axis=-1)

    def to_json(self) -> str:
        """JSON description (names, prior types and arguments, transforms)."""
        items = []
        for name, prior, tr in zip(self.names, self.priors, self.transforms, strict=True):
            args = {k: float(v) for k, v in vars(prior).items()}
            items.append({"name": name, "prior": type(prior).__name__, "args": args,
                          "transform": tr})
        return json.dumps(items)

    @classmethod
    def from_json(cls, text: str) -> PriorSet:
        """Inverse of :meth:`to_json`."""
        kinds = {"Uniform": Uniform, "LogUniform": LogUniform, "Normal": Normal}
        try:
            items = json.loads(text)
            priors = tuple(kinds[it["prior"]](**it["args"]) for it in items)
            return cls(tuple(it["name"] for it in items), priors,
                       tuple(it["transform"] for it in items))
        except (KeyError, TypeError, json.JSONDecodeError) as exc:
            raise ConfigError(f"not a prior description: {exc}") from exc

    def sample(self, n: int, rng=None) -> np.ndarray:
        """Draws from the prior, shape (n, P)."""
        rng = np.random.default_rng(rng)
        return self.prior_transform(rng.random((n, self.n_params)))


def default_priors(
    model,
    *,
    noise: str = "ar1",
    n_outputs: int | None = None,
    overrides: Mapping[str, object] | None = None,
    extension=None,
    initial_states: Sequence[str] = (),
) -> PriorSet:
    """Documented default priors for a rig model and a noise model.

    Parameters
    ----------
    model : LinearModel
    noise : {"ar1", "white"}
    n_outputs : int, optional
        Number of measured outputs (default: the rig's sensors, one per cart for a chain).
    overrides : mapping of str to prior, optional
        Per-parameter replacements, e.g. ``{"g_v": Normal(6.2, 0.5, lo=0)}``.
    extension : str or Extension, optional
        A model extension (free damping only); its parameters get ``Uniform`` priors on
        their ``ParamSpec.bounds`` (see the module docstring for the transforms).
    initial_states : sequence of str
        Names of estimated initial states (``Likelihood.initial_state_names``): uniform on
        +-0.1 m for positions ``x*``, +-2 m/s for velocities ``v*``.

    Returns
    -------
    PriorSet
        Parameters ordered as ``model.names`` (or ``extension.names(model.rig)``), the
        initial states, then ``noise_names(n_outputs, noise)``.  For a rig other than the
        chain: the same priors by parameter kind, and for an unknown spring
        ``Normal(stiffness_n_m, prior_sd_n_m, lo=0)`` or, without ``prior_sd_n_m``,
        ``Uniform(stiffness_n_m / 10, 10 stiffness_n_m)`` (log transform).

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> ps = default_priors(LinearModel(Rig(), "free"), noise="white",
    ...                     extension="coulomb_friction")
    >>> ps.names[9:12], ps.priors[9]
    (('Fc1', 'Fc2', 'Fc3'), Uniform(lo=0.0, hi=2.0))
    """
    n = model.n_carts
    n_out = model.n_outputs if n_outputs is None else int(n_outputs)
    names, priors, trs = [], [], []

    def add(nm, prior, tr):
        names.append(nm)
        priors.append(prior)
        trs.append(tr)

    mech = model.names
    if not model.rig.is_chain:
        _layout_priors(model, add)
    else:
        add("g_v", Uniform(1.0, 15.0), "log")
        for i in range(n):
            add(f"m{i + 1}", Uniform(0.2, 5.0), "log")
        if model.damping == "proportional":
            add("ca", Uniform(0.0, 20.0), "log")
            add("cb", Uniform(0.0, 0.01), "identity")
        else:
            for nm in mech[1 + n :]:
                add(nm, Uniform(0.0, 20.0), "identity")
    if tuple(names) != tuple(mech):  # pragma: no cover - guards against a model change
        raise ConfigError(f"default priors do not match the model parameters {mech}")
    for nm in initial_states:
        # initial positions within 10 cm, velocities within 2 m/s of rest
        add(nm, Uniform(-0.1, 0.1) if nm.startswith("x") else Uniform(-2.0, 2.0), "identity")
    if extension is not None:
        ext = resolve_extension(extension, model)
        for spec in ext.specs(model.rig):
            lo, hi = (float(b) for b in spec.bounds)
            add(spec.name, Uniform(lo, hi), "log" if lo > 0 else "identity")
    kinds = (model.rig.output_kinds if n_out == model.n_outputs
             else ("position",) * n_out)
    for nm in noise_names(n_out, noise):
        if nm.startswith("sigma"):
            j = int(nm.rsplit("_", 1)[1]) - 1 if nm[6:].isdigit() else 0
            add(nm, LogUniform(*SIGMA_PRIOR_BOUNDS[kinds[min(j, n_out - 1)]]), "log")
        else:
            add(nm, Uniform(-1.0, 1.0), "tanh")
    ps = PriorSet(tuple(names), tuple(priors), tuple(trs))
    return ps.replace(overrides) if overrides else ps


def _layout_priors(model, add) -> None:
    """Default priors of a non-chain rig, by parameter kind (the chain's values)."""
    springs = {s.name: s for s in model.rig.springs}
    for nm, kind in zip(model.names, param_kinds(model), strict=True):
        if kind == "gain":
            add(nm, Uniform(1.0, 15.0), "log")
        elif kind == "mass":
            add(nm, Uniform(0.2, 5.0), "log")
        elif kind == "ca":
            add(nm, Uniform(0.0, 20.0), "log")
        elif kind == "cb":
            add(nm, Uniform(0.0, 0.01), "identity")
        elif kind == "spring":
            s = springs[nm]
            k = s.stiffness_n_m
            prior = (Uniform(k / 10, 10 * k) if s.prior_sd_n_m is None
                     else Normal(k, s.prior_sd_n_m, lo=0.0))
            add(nm, prior, "log")
        else:
            add(nm, Uniform(0.0, 20.0), "identity")
