"""Convergence of an ensemble run: autocorrelation times, R-hat, bulk ESS and the warning.

``convergence_diagnostics`` reads a chain after burn-in (emcee's integrated
autocorrelation time, ArviZ's rank-normalised split R-hat and bulk ESS over the walkers as
chains) into :class:`Diagnostics`; a run that fails the checks warns with
:class:`ConvergenceWarning` naming what failed and the fix.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import emcee
import numpy as np

from .idata import arviz

__all__ = ["ConvergenceWarning", "Diagnostics", "convergence_diagnostics"]


class ConvergenceWarning(UserWarning):
    """The MCMC run does not pass the convergence checks."""


@dataclass(frozen=True)
class Diagnostics:
    """Convergence diagnostics of an ensemble run (post burn-in).

    Attributes
    ----------
    tau : ndarray, shape (P,)
        Integrated autocorrelation time per parameter, steps.
    n_over_tau : float
        Post-burn-in steps divided by the largest tau (want > 50).
    acceptance : float
        Mean acceptance fraction over walkers.
    rhat : ndarray, shape (P,)
        Rank-normalised split R-hat (ArviZ), walkers as chains.
    ess_bulk : ndarray, shape (P,)
        Bulk effective sample size (ArviZ) of the post-burn-in draws.
    max_rhat, min_ess : float
    converged : bool
    problems : tuple of str
        Human-readable reasons when not converged.
    """

    tau: np.ndarray
    n_over_tau: float
    acceptance: float
    rhat: np.ndarray
    ess_bulk: np.ndarray
    max_rhat: float
    min_ess: float
    converged: bool
    problems: tuple[str, ...] = ()


def convergence_diagnostics(
    chain: np.ndarray,
    acceptance: np.ndarray,
    names: Sequence[str],
    *,
    min_n_over_tau: float = 50.0,
    max_rhat: float = 1.05,
    min_ess: float = 100.0,
    acceptance_range: tuple[float, float] = (0.1, 0.8),
) -> Diagnostics:
    """Autocorrelation time, acceptance, R-hat and ESS of a post-burn-in ensemble chain.

    Parameters
    ----------
    chain : ndarray, shape (n_steps, n_walkers, P)
        Post-burn-in chain (unthinned).
    acceptance : ndarray, shape (n_walkers,)
    names : sequence of str, length P
    min_n_over_tau, max_rhat, min_ess, acceptance_range
        Thresholds.  R-hat uses walkers as chains; walkers of an ensemble are not
        independent, so the threshold is looser than the 1.01 used for independent chains.

    Returns
    -------
    Diagnostics
    """

    az = arviz()
    n_steps = chain.shape[0]
    # tol=0: always return the estimate; the length check is ours (below), not emcee's log
    # a parameter that no walker has moved yet (a very short run) has a zero
    # autocovariance: its tau is NaN, counted as not converged below, not an error
    with np.errstate(invalid="ignore", divide="ignore"):
        tau = emcee.autocorr.integrated_time(chain, tol=0) if n_steps > 1 else np.full(
            chain.shape[-1], np.inf)
    tau = np.asarray(tau, dtype=float)
    tau = np.where(np.isnan(tau), np.inf, tau)
    tau_max = float(np.nanmax(tau)) if tau.size else np.inf
    n_over = n_steps / tau_max if tau_max > 0 else np.inf
    import xarray as xr

    # (chain, draw) as ArviZ wants; built directly, because convert_to_dataset warns for
    # short runs with more walkers than steps
    ds = xr.Dataset({nm: (("chain", "draw"), chain[:, :, i].T) for i, nm in enumerate(names)})
    rh = az.rhat(ds)
    es = az.ess(ds, method="bulk")
    rhat = np.array([float(rh[nm]) for nm in names])
    ess = np.array([float(es[nm]) for nm in names])
    acc = float(np.mean(acceptance))
    problems = []
    if not n_over > min_n_over_tau:
        problems.append(f"chain is {n_over:.1f} autocorrelation times long (want > "
                        f"{min_n_over_tau:g}; max tau {tau_max:.0f} steps)")
    # (too few kept steps leave R-hat and ESS undefined for every parameter: NaN)
    rmax = float(np.nanmax(rhat)) if np.any(~np.isnan(rhat)) else np.nan
    emin = float(np.nanmin(ess)) if np.any(~np.isnan(ess)) else np.nan
    if np.isnan(rmax) or np.isnan(emin):
        problems.append(f"R-hat and bulk ESS undefined on a chain of {n_steps} kept steps "
                        "(run more steps after the burn-in)")
    else:
        if not rmax < max_rhat:
            worst = names[int(np.nanargmax(rhat))]
            problems.append(f"max R-hat {rmax:.3f} ({worst}) >= {max_rhat}")
        if not emin > min_ess:
            worst = names[int(np.nanargmin(ess))]
            problems.append(f"min bulk ESS {emin:.0f} ({worst}) <= {min_ess:g}")
    lo, hi = acceptance_range
    if not lo < acc < hi:
        problems.append(f"mean acceptance {acc:.2f} outside ({lo}, {hi})")
    return Diagnostics(
        tau=tau,
        n_over_tau=float(n_over),
        acceptance=acc,
        rhat=rhat,
        ess_bulk=ess,
        max_rhat=rmax,
        min_ess=emin,
        converged=not problems,
        problems=tuple(problems),
    )


