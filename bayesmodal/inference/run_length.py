"""How many steps a finished ensemble run needed: the shortest prefix that stays converged.

A run is sized before it starts (``[sampler] steps``), usually with a margin.  Once it is
finished, its own chain says how long it had to be: the diagnostics of every prefix of the
post-burn-in chain are what a shorter run with the same seed would have reported, because
an ensemble sampler's first ``k`` steps do not depend on how many steps follow.  The
first prefix at which R-hat and ESS cross their thresholds is an optimistic stopping rule
(R-hat fluctuates, and stopping at its first dip selects a dip), so ``converged_from``
returns the shortest prefix *from which every longer checked prefix is converged too*.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError
from .sampling import convergence_diagnostics

__all__ = ["RunLength", "converged_from"]


@dataclass(frozen=True)
class RunLength:
    """The prefixes of a post-burn-in chain that were checked, and the lasting one.

    Attributes
    ----------
    kept_steps : ndarray of int, shape (K,)
        Post-burn-in prefix lengths checked, steps per walker, increasing; the last is
        the whole chain.
    max_rhat, min_ess : ndarray, shape (K,)
        Largest rank-normalised split R-hat and smallest bulk ESS at each prefix.
    converged : ndarray of bool, shape (K,)
        ``max_rhat < max_rhat_target`` and ``min_ess > min_ess_target`` at each prefix.
    lasting : int or None
        The shortest checked prefix from which every longer one is converged (steps per
        walker after the burn-in); None when the whole chain is not converged.
    """

    kept_steps: np.ndarray
    max_rhat: np.ndarray
    min_ess: np.ndarray
    converged: np.ndarray
    lasting: int | None


def converged_from(chain: np.ndarray, names: Sequence[str], *, every: int,
                   max_rhat: float = 1.05, min_ess: float = 400.0) -> RunLength:
    """The shortest prefix of a post-burn-in chain that converges and stays converged.

    Parameters
    ----------
    chain : ndarray, shape (n_steps, n_walkers, P)
        Post-burn-in chain (walkers of several ensembles side by side count as chains).
    names : sequence of str, length P
    every : int
        Spacing of the checked prefixes, steps (``every, 2 every, ...`` and the whole
        chain).  Each check computes R-hat and bulk ESS of the prefix (ArviZ).
    max_rhat, min_ess : float
        Thresholds (strict: R-hat below, ESS above), as issue 16 states them.

    Returns
    -------
    RunLength
    """
    chain = np.asarray(chain, dtype=float)
    if chain.ndim != 3 or chain.shape[2] != len(names):
        raise ConfigError(f"chain must have shape (steps, walkers, {len(names)}), got "
                          f"{chain.shape}")
    every = int(every)
    if every < 4:
        raise ConfigError(f"every = {every}: check prefixes at least 4 steps apart")
    n = chain.shape[0]
    if n < every:
        raise ConfigError(f"the chain has {n} steps, fewer than every = {every}; give a "
                          f"smaller spacing")
    ks = list(range(every, n + 1, every))
    if ks[-1] != n:
        ks.append(n)
    rh, es = [], []
    for k in ks:
        d = convergence_diagnostics(chain[:k], np.ones(chain.shape[1]), names,
                                    max_rhat=max_rhat, min_ess=min_ess)
        rh.append(d.max_rhat)
        es.append(d.min_ess)
    rh, es = np.array(rh), np.array(es)
    ok = (rh < max_rhat) & (es > min_ess)
    lasting = None
    if ok[-1]:
        bad = np.flatnonzero(~ok)  # the prefixes that are not converged
        i = 0 if bad.size == 0 else int(bad[-1]) + 1
        lasting = int(ks[i])
    return RunLength(np.array(ks), rh, es, ok, lasting)
