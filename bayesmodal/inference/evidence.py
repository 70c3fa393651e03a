"""The evidence of a model by nested sampling, and the Bayes factor of two.

``Z = int L(theta) p(theta) dtheta`` by static nested sampling (dynesty, an optional
library), with its error.  It depends on the prior ranges (a wider prior on an unneeded
parameter costs ``log(width ratio)``), which the report states next to it.  The Bayes
factor ``B = Z_a / Z_b`` is read on the Kass and Raftery (1995) scale of ``2 ln B``.
:mod:`bayesmodal.inference.compare` puts it beside the other criteria.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError
from .priors import PriorSet

__all__ = ["Evidence", "nested_evidence", "BayesFactor", "bayes_factor", "kass_raftery"]


# ----------------------------------------------------------------------------- evidence
@dataclass(frozen=True)
class Evidence:
    """Marginal likelihood of a model.

    Attributes
    ----------
    log_z : float
        Natural log of the evidence.
    log_z_err : float
        Its standard error (dynesty's estimate from the prior-volume statistics).
    information_nats : float
        Kullback-Leibler divergence from prior to posterior (nats).
    n_calls : int
        Likelihood evaluations.
    n_iterations : int
    elapsed_s : float
    method : str
    """

    log_z: float
    log_z_err: float
    information_nats: float
    n_calls: int
    n_iterations: int
    elapsed_s: float
    method: str = "dynesty"


def nested_evidence(
    log_likelihood: Callable[[np.ndarray], np.ndarray],
    priors: PriorSet,
    *,
    nlive: int = 300,
    dlogz: float = 0.5,
    sample: str = "rwalk",
    rng=None,
    maxcall: int | None = None,
) -> Evidence:
    """Evidence by static nested sampling with dynesty.

    Parameters
    ----------
    log_likelihood : callable
        Batched log-likelihood, ``f(theta of shape (nb, P)) -> (nb,)`` in ``priors.names``
        order (a :class:`~.likelihood.Likelihood` qualifies).
    priors : PriorSet
        Supplies the prior transform from the unit cube.
    nlive : int
        Live points.
    dlogz : float
        Stopping criterion on the remaining evidence, nats.
    sample : str
        dynesty sampling method.
    rng : numpy.random.Generator or int, optional
    maxcall : int, optional
        Hard limit on likelihood calls; a run stopped by it warns.

    Returns
    -------
    Evidence

    Examples
    --------
    A Gaussian likelihood with unit width under a Uniform(-10, 10) prior has
    ``Z = 1/20``:

    >>> from bayesmodal.inference.priors import PriorSet, Uniform
    >>> ps = PriorSet(("x",), (Uniform(-10.0, 10.0),), ("identity",))
    >>> f = lambda th: -0.5 * th[:, 0] ** 2 - 0.5 * np.log(2 * np.pi)
    >>> ev = nested_evidence(f, ps, nlive=100, rng=1)
    >>> bool(abs(ev.log_z - np.log(1 / 20)) < 4 * ev.log_z_err)
    True
    """
    try:
        import dynesty
    except ImportError:
        raise ConfigError("nested sampling of the evidence needs the optional library "
                          "dynesty: pip install 'bayesmodal[evidence]'") from None

    gen = np.random.default_rng(rng)
    calls = [0]

    def loglike(x):
        calls[0] += 1
        v = float(np.asarray(log_likelihood(np.asarray(x)[None]))[0])
        # dynesty needs finite values; impossible points are simply very unlikely
        return v if np.isfinite(v) else -1e300

    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sampler = dynesty.NestedSampler(loglike, priors.prior_transform, priors.n_params,
                                        nlive=int(nlive), sample=sample, rstate=gen)
        sampler.run_nested(dlogz=dlogz, print_progress=False, maxcall=maxcall)
    for w in caught:
        if "stopped short" in str(w.message):
            warnings.warn(f"nested sampling stopped at maxcall={maxcall} before dlogz={dlogz}; "
                          "the evidence is a lower bound", RuntimeWarning, stacklevel=2)
    res = sampler.results
    return Evidence(
        log_z=float(res.logz[-1]),
        log_z_err=float(res.logzerr[-1]),
        information_nats=float(res.information[-1]),
        n_calls=int(calls[0]),
        n_iterations=int(res.niter),
        elapsed_s=time.perf_counter() - t0,
    )


# ----------------------------------------------------------------------------- Bayes factor
def kass_raftery(two_ln_b: float) -> str:
    """Kass and Raftery (1995) reading of ``2 ln B`` (B in favour of the better model)."""
    x = abs(float(two_ln_b))
    if x < 2:
        return "not worth more than a bare mention"
    if x < 6:
        return "positive"
    if x < 10:
        return "strong"
    return "very strong"


@dataclass(frozen=True)
class BayesFactor:
    """Bayes factor of model ``a`` over model ``b``.

    Attributes
    ----------
    a, b : str
    log_bf : float
        ``ln Z_a - ln Z_b``.
    log_bf_err : float
        ``sqrt(err_a^2 + err_b^2)``.
    two_ln_b : float
        ``2 |ln B|`` for the favoured model.
    favoured : str
    reading : str
        Kass-Raftery category of ``two_ln_b``.
    """

    a: str
    b: str
    log_bf: float
    log_bf_err: float
    two_ln_b: float
    favoured: str
    reading: str


def bayes_factor(evidences: Mapping[str, Evidence], a: str, b: str) -> BayesFactor:
    """Bayes factor ``Z_a / Z_b`` with its error and Kass-Raftery reading."""
    ea, eb = evidences[a], evidences[b]
    lbf = ea.log_z - eb.log_z
    return BayesFactor(
        a=a, b=b, log_bf=lbf,
        log_bf_err=math.hypot(ea.log_z_err, eb.log_z_err),
        two_ln_b=2 * abs(lbf),
        favoured=a if lbf >= 0 else b,
        reading=kass_raftery(2 * lbf),
    )
