"""What coverage a calibrated predictive band would show on one record: its own reference.

The coverage of a predictive band on one record (the share of its samples inside the band)
is a single draw of a random quantity.  When the record's misfit is correlated over
hundreds of samples (an AR(1) discrepancy with ``phi`` near 1, a slowly drifting rest
position), a record holds only a handful of independent stretches, and a band that is
exactly calibrated still covers, say, 75 % of one record and 100 % of the next.  A fixed
window such as 85-95 % then says nothing: it fails calibrated bands and passes wrong ones.

The predictive ensemble carries its own answer.  If the model were right, the measured
record would be one more draw from the predictive distribution, exchangeable with the
ensemble members.  So each member ``j`` is scored against the band of the *other*
``S - 1`` members exactly as the record is scored against the band of all ``S``: the
``S`` coverages so obtained are draws of the coverage a calibrated band shows on a record
like this one, with the record's length, its correlation and its start.  Their quantiles
are the range to expect, and the rank of the measured coverage among them (its PIT) says
how unusual the record is: uniform on (0, 1) over records when the band is calibrated,
near 0 when it is too narrow, near 1 when it is wider than it needs to be.  The same is
done for the band factor (``band_factor_90``: how far outside the band the misses lie).

The member's leave-one-out band uses NumPy's default (linear) quantile of the other
members, computed from the ensemble sorted once: with the member's rank ``r`` among all
``S``, the ``i``-th of the others is the ``i``-th sorted member for ``i < r`` and the
``(i + 1)``-th otherwise, so no quantile is recomputed per member.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from .._errors import ConfigError

__all__ = ["COVERAGE_WINDOW_90", "CoverageReference", "MIN_REFERENCE_DRAWS",
           "calibration_summary", "coverage_reference", "pit", "reference_fields"]

#: Fewest predictive members for a reference (below it the leave-one-out bands are too
#: coarse: the 5 % quantile of 19 members is an order statistic of one or two of them).
MIN_REFERENCE_DRAWS = 20

#: A fixed acceptance window for the coverage of a 90 % band on one record (every record
#: and output covered 80-95 %): :meth:`CoverageReference.window_probability` gives how
#: often a calibrated band meets it.
COVERAGE_WINDOW_90 = (0.80, 0.95)

#: Members scored per block (bounds the (block, N, n_out) temporaries).
_BLOCK = 32


def pit(reference: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """Mid-rank probability integral transform of ``observed`` in ``reference``.

    Parameters
    ----------
    reference : ndarray, shape (S, ...)
        Draws of the reference distribution along the first axis.
    observed : ndarray, shape (...)

    Returns
    -------
    ndarray, shape (...)
        ``(#{ref < obs} + #{ref == obs} / 2) / S``: uniform on (0, 1) when ``observed`` is
        exchangeable with the draws (ties, e.g. several draws covering 100 %, are split).

    Examples
    --------
    >>> float(pit(np.array([0.1, 0.5, 0.9, 1.0]), np.array(0.9)))
    0.625
    """
    ref = np.asarray(reference, dtype=float)
    obs = np.asarray(observed, dtype=float)[None]
    return (np.sum(ref < obs, axis=0) + 0.5 * np.sum(ref == obs, axis=0)) / ref.shape[0]


@dataclass(frozen=True)
class CoverageReference:
    """Coverages a calibrated band shows on records like the one predicted.

    Attributes
    ----------
    probs : tuple of float
        Central band probabilities scored, e.g. ``(0.5, 0.9)``.
    coverage : ndarray, shape (n_probs, S, n_out)
        Each ensemble member's coverage of the band of the other members.
    band_factor_90 : ndarray, shape (S, n_out)
        Each member's factor on the 90 % band of the others that would cover 90 % of it
        (``predictive.band_factor``).
    """

    probs: tuple[float, ...]
    coverage: np.ndarray
    band_factor_90: np.ndarray

    @property
    def n_draws(self) -> int:
        return int(self.coverage.shape[1])

    def _k(self, prob: float) -> int:
        try:
            return self.probs.index(prob)
        except ValueError:
            raise ConfigError(f"no reference for a {prob} band; have {self.probs}") from None

    def interval(self, prob: float = 0.9, level: float = 0.9) -> np.ndarray:
        """Central ``level`` range of the coverage of a calibrated ``prob`` band.

        Returns
        -------
        ndarray, shape (n_out, 2)
            Lower and upper quantile per output (fractions).
        """
        q = np.quantile(self.coverage[self._k(prob)], [(1 - level) / 2, (1 + level) / 2],
                        axis=0)
        return q.T

    def band_factor_interval(self, level: float = 0.9) -> np.ndarray:
        """Central ``level`` range of the 90 % band factor, shape (n_out, 2)."""
        return np.quantile(self.band_factor_90, [(1 - level) / 2, (1 + level) / 2],
                           axis=0).T

    def coverage_pit(self, coverage: np.ndarray, prob: float = 0.9) -> np.ndarray:
        """PIT of a record's coverage per output, shape (n_out,)."""
        return pit(self.coverage[self._k(prob)], coverage)

    def record_pit(self, coverage: np.ndarray, prob: float = 0.9) -> float:
        """PIT of a record's coverage averaged over its outputs (one number per record:
        the outputs of one record share most of their misfit, so they are not independent
        evidence)."""
        return float(pit(self.coverage[self._k(prob)].mean(axis=1),
                         np.mean(coverage)))

    def record_band_factor_pit(self, band_factor: np.ndarray) -> float:
        """PIT of a record's 90 % band factor averaged over its outputs: near 1 when its
        misses lie further outside the band than a calibrated band's would."""
        return float(pit(self.band_factor_90.mean(axis=1), np.mean(band_factor)))

    def window_probability(self, window: tuple[float, float] = COVERAGE_WINDOW_90,
                           prob: float = 0.9) -> float:
        """Probability that a calibrated ``prob`` band covers a record like this one
        within ``window`` on every output at once."""
        c = self.coverage[self._k(prob)]
        return float(np.mean(np.all((c >= window[0]) & (c <= window[1]), axis=1)))


def _loo_quantile(xs: np.ndarray, rank: np.ndarray, p: float) -> np.ndarray:
    """NumPy's linear ``p`` quantile of the ensemble without each member.

    ``xs`` (S, N, n) is the ensemble sorted along axis 0, ``rank`` (B, N, n) the ranks of
    B members in it; returns (B, N, n)."""
    s = xs.shape[0]
    a = p * (s - 2)                    # position among the S - 1 others
    lo = int(np.floor(a))
    hi = min(lo + 1, s - 2)
    frac = a - lo

    def other(i):                      # the i-th of the others: skip the member itself
        return np.where(i < rank, xs[i], xs[i + 1])

    o_lo = other(lo)
    return o_lo + frac * (other(hi) - o_lo)


def coverage_reference(samples: np.ndarray, probs: tuple[float, ...] = (0.5, 0.9)
                       ) -> CoverageReference:
    """Score every member of a predictive ensemble against the band of the others.

    Parameters
    ----------
    samples : ndarray, shape (S, N, n_out)
        Predictive samples of one record (S >= :data:`MIN_REFERENCE_DRAWS`).
    probs : tuple of float
        Central band probabilities, each in (0, 1); 0.9 is always added (band factor).

    Returns
    -------
    CoverageReference

    Examples
    --------
    A calibrated ensemble of independent samples covers about 90 % of each member:

    >>> rng = np.random.default_rng(0)
    >>> ref = coverage_reference(rng.standard_normal((100, 2000, 1)))
    >>> bool(abs(np.median(ref.coverage[1]) - 0.9) < 0.02)
    True
    """
    x = np.asarray(samples, dtype=float)
    if x.ndim != 3:
        raise ConfigError(f"samples must have shape (S, N, n_out), got {x.shape}")
    s = x.shape[0]
    if s < MIN_REFERENCE_DRAWS:
        raise ConfigError(f"a coverage reference needs at least {MIN_REFERENCE_DRAWS} "
                          f"predictive draws, got {s}; draw more (n_predictive)")
    probs = tuple(float(p) for p in probs)
    if 0.9 not in probs:
        probs = probs + (0.9,)
    if not all(0.0 < p < 1.0 for p in probs):
        raise ConfigError(f"band probabilities must be in (0, 1), got {probs}")
    order = np.argsort(x, axis=0, kind="stable")
    xs = np.take_along_axis(x, order, axis=0)
    rank = np.empty_like(order)
    np.put_along_axis(rank, order, np.arange(s).reshape(s, 1, 1), axis=0)
    cov = np.empty((len(probs), s, x.shape[2]))
    factor = np.empty((s, x.shape[2]))
    for b0 in range(0, s, _BLOCK):
        sl = slice(b0, min(s, b0 + _BLOCK))
        r, xj = rank[sl], x[sl]
        for k, p in enumerate(probs):
            lo = _loo_quantile(xs, r, (1 - p) / 2)
            hi = _loo_quantile(xs, r, (1 + p) / 2)
            cov[k, sl] = np.mean((xj >= lo) & (xj <= hi), axis=1)
            if p == 0.9:
                lo90, hi90 = lo, hi
        med = _loo_quantile(xs, r, 0.5)
        with np.errstate(divide="ignore", invalid="ignore"):
            need = np.where(xj >= med, (xj - med) / (hi90 - med), (med - xj) / (med - lo90))
        need = np.where(xj == med, 0.0, need)
        factor[sl] = np.quantile(need, 0.9, axis=1, method="inverted_cdf")
    return CoverageReference(probs, cov, factor)


def reference_fields(ref: CoverageReference, coverage: dict[float, np.ndarray],
                     band_factor_90: np.ndarray | None = None) -> dict:
    """A record's scores against its reference, in ``summary.json`` form.

    Parameters
    ----------
    ref : CoverageReference
    coverage : dict
        The record's coverage (n_out,) per band probability, e.g. ``{0.9: c90}``.
    band_factor_90 : ndarray, shape (n_out,), optional

    Returns
    -------
    dict
        ``coverage_<pct>_expected`` (per output ``[lo, hi]``: the central 90 % of a
        calibrated band's coverage) and ``coverage_<pct>_pit``; ``record_pit_90`` and
        ``window_probability_90``; with ``band_factor_90`` also
        ``band_factor_90_expected``, ``band_factor_90_pit`` and
        ``record_band_factor_pit_90``.
    """
    d = {}
    for p, cov in coverage.items():
        k = f"coverage_{round(100 * p)}"
        d[f"{k}_expected"] = ref.interval(p).tolist()
        d[f"{k}_pit"] = ref.coverage_pit(cov, p).tolist()
    d["record_pit_90"] = ref.record_pit(coverage[0.9])
    d["window_probability_90"] = ref.window_probability()
    if band_factor_90 is not None:
        d["band_factor_90_expected"] = ref.band_factor_interval().tolist()
        d["band_factor_90_pit"] = np.asarray(pit(ref.band_factor_90, band_factor_90)).tolist()
        d["record_band_factor_pit_90"] = ref.record_band_factor_pit(band_factor_90)
    return d


def calibration_summary(record_pits: list[float], level: float = 0.9,
                        window_probabilities: list[float] | None = None,
                        band_factor_pits: list[float] | None = None) -> dict:
    """Are several records' coverages consistent with calibrated bands?

    Parameters
    ----------
    record_pits : list of float
        One :meth:`CoverageReference.record_pit` per record (independent records: e.g.
        the folds of a leave-one-record-out study).
    level : float
        A record is *outside* when its PIT falls outside the central ``level`` range.
    window_probabilities : list of float, optional
        :meth:`CoverageReference.window_probability` per record.
    band_factor_pits : list of float, optional
        :meth:`CoverageReference.record_band_factor_pit` per record: counted apart
        (``n_band_factor_below``, ``..._above``), since a band can cover a typical share
        of a record and miss the rest far outside.

    Returns
    -------
    dict
        ``record_pit_90``, ``n_outside`` (``n_below``, ``n_above``), ``p_value`` (the
        binomial probability of at least ``n_outside`` records outside if every band were
        calibrated), and with ``window_probabilities`` their product
        ``window_probability_all``: how often calibrated bands meet the fixed window on
        every record and output at once.

    Examples
    --------
    >>> calibration_summary([0.5, 0.97, 0.2, 0.6])["n_outside"]
    1
    """
    u = np.asarray(record_pits, dtype=float)
    a = (1 - level) / 2
    below, above = int(np.sum(u < a)), int(np.sum(u > 1 - a))
    k = below + above
    out = {"record_pit_90": u.tolist(), "level": level, "n_records": int(u.size),
           "n_below": below, "n_above": above, "n_outside": k,
           "p_value": float(stats.binom.sf(k - 1, u.size, 1 - level)) if u.size else
           float("nan")}
    if band_factor_pits is not None:
        f = np.asarray(band_factor_pits, dtype=float)
        out["record_band_factor_pit_90"] = f.tolist()
        out["n_band_factor_below"] = int(np.sum(f < a))
        out["n_band_factor_above"] = int(np.sum(f > 1 - a))
    if window_probabilities is not None:
        out["window"] = list(COVERAGE_WINDOW_90)
        out["window_probability"] = [float(p) for p in window_probabilities]
        out["window_probability_all"] = float(np.prod(window_probabilities))
    return out
