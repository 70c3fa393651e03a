"""The three questions a run must answer first, in plain words, from its ``summary.json``.

1. Did the sampler converge?  (R-hat, effective sample size.)
2. Does the model explain the data?  (Residual diagnostics, fit percentages, held-out
   records.)
3. How far can the intervals be trusted?  Posterior intervals are conditional on the
   model: when the model does not explain the data they describe the parameters of the
   best wrong model, and say nothing about how wrong it is.  Evidence: other estimators
   (least squares, LSCE) inside or outside them, and how much of new records (held-out or
   left-out records) the 90 % predictive band covers.

The answers are statuses ``"ok"``, ``"bad"`` or ``"unknown"`` with one sentence each, and
an overall sentence; the report shows them on its first screen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Answer", "RunVerdict", "run_verdict", "cell_statuses", "coverage_status",
           "record_status",
           "COVERAGE_TOLERANCE", "VERDICT_FAMILY_LEVEL"]

#: Without a coverage reference (summaries written before it, or too few predictive
#: draws), a 90 % predictive band is taken as "covering" new records when it covers at
#: least 90 % - this (fraction), and as wider than needed above 90 % + this.
COVERAGE_TOLERANCE = 0.05

#: Probability with which the verdict calls *calibrated* bands too narrow or too wide
#: somewhere among the records it checks (two statistics per record, Bonferroni):
#: a record is flagged when the rank of its coverage or of its band factor among what a
#: calibrated band shows (``inference.coverage_reference``) is in a tail of
#: ``VERDICT_FAMILY_LEVEL / (4 n_records)``.
VERDICT_FAMILY_LEVEL = 0.1


def coverage_status(coverage: float, prob: float = 0.9, *, coverage_pit: float | None = None,
                    band_factor_pit: float | None = None, level: float = 0.9) -> str:
    """How honest a band of probability ``prob`` is that covers ``coverage`` of a record.

    With the record's coverage reference (``coverage_pit``: the rank of its coverage
    among the coverages a calibrated band shows on such a record; ``band_factor_pit``:
    the same for the factor that would make the band cover ``prob``): ``"narrow"`` when
    the coverage is in the lower tail or the band factor in the upper tail of the central
    ``level`` range (the misses lie further out than a calibrated band's), ``"wide"`` in
    the opposite tails, ``"ok"`` otherwise.  Without it: ``"ok"`` within ``prob +-
    COVERAGE_TOLERANCE``, ``"narrow"`` below, ``"wide"`` above.

    Examples
    --------
    >>> [coverage_status(c) for c in (0.5, 0.88, 0.93, 1.0)]
    ['narrow', 'ok', 'ok', 'wide']
    >>> coverage_status(0.99, coverage_pit=0.8, band_factor_pit=0.3)  # 99 % is typical
    'ok'
    >>> coverage_status(0.83, coverage_pit=0.2, band_factor_pit=0.99)  # far misses
    'narrow'
    """
    if coverage_pit is None:
        if coverage < prob - COVERAGE_TOLERANCE:
            return "narrow"
        if coverage > min(1.0, prob + COVERAGE_TOLERANCE):
            return "wide"
        return "ok"
    a = (1.0 - level) / 2
    f = 0.5 if band_factor_pit is None else band_factor_pit
    if coverage_pit < a or f > 1.0 - a:
        return "narrow"
    if coverage_pit > 1.0 - a or f < a:
        return "wide"
    return "ok"


def record_status(record: dict, n_records: int = 1, prob: float = 0.9) -> str:
    """``"narrow"``, ``"wide"`` or ``"ok"`` for one scored record (``summary.json`` form).

    With ``record_pit_90`` (and ``record_band_factor_pit_90``) the record-level ranks are
    tested at the family-wise :data:`VERDICT_FAMILY_LEVEL` over ``n_records`` records;
    without, the lowest and highest coverage of its outputs against the fixed tolerance.
    """
    u = record.get("record_pit_90")
    if _finite(u):
        v = record.get("record_band_factor_pit_90")
        level = 1.0 - VERDICT_FAMILY_LEVEL / (2 * max(1, n_records))
        return coverage_status(float("nan"), prob, coverage_pit=float(u),
                               band_factor_pit=float(v) if _finite(v) else None,
                               level=level)
    cov = _flat(record.get("coverage_90", []))
    if not cov:
        return "ok"
    lo, hi = coverage_status(min(cov), prob), coverage_status(max(cov), prob)
    return "narrow" if "narrow" in (lo, hi) else ("wide" if "wide" in (lo, hi) else "ok")


def cell_statuses(record: dict, prob: float = 0.9) -> list[str]:
    """``coverage_status`` of each output of a scored record (its reference where given)."""
    cov = _flat(record.get("coverage_90", []))
    cp = record.get("coverage_90_pit") or [None] * len(cov)
    fp = record.get("band_factor_90_pit") or [None] * len(cov)
    return [coverage_status(c, prob, coverage_pit=u, band_factor_pit=f)
            for c, u, f in zip(cov, cp, fp, strict=False)]


@dataclass(frozen=True)
class Answer:
    """One of the three questions.

    Attributes
    ----------
    question : str
    status : str
        ``"ok"``, ``"bad"`` or ``"unknown"`` (not enough information in the summary).
    text : str
        The answer in one or two sentences, with its numbers.
    """

    question: str
    status: str
    text: str


@dataclass(frozen=True)
class RunVerdict:
    """The first-screen verdict of a run.

    Attributes
    ----------
    sampler, model, intervals : Answer
        Did the sampler converge; does the model explain the data; how far can the
        intervals be trusted.
    sentence : str
        Overall verdict in one sentence.
    ok : bool
        True only when all three answers are ``"ok"``.
    """

    sampler: Answer
    model: Answer
    intervals: Answer
    sentence: str
    ok: bool

    @property
    def answers(self) -> tuple[Answer, Answer, Answer]:
        return (self.sampler, self.model, self.intervals)


def _finite(x) -> bool:
    try:
        return x is not None and math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def _flat(x) -> list[float]:
    out: list[float] = []
    for v in x if isinstance(x, (list, tuple)) else [x]:
        if isinstance(v, (list, tuple)):
            out.extend(_flat(v))
        elif _finite(v):
            out.append(float(v))
    return out


def _span(values, fmt: str = ".0f", scale: float = 1.0, unit: str = " %") -> str:
    v = [scale * x for x in _flat(values)]
    if not v:
        return "?"
    lo, hi = min(v), max(v)
    a, b = format(lo, fmt), format(hi, fmt)
    return f"{a}{unit}" if a == b else f"{a}-{b}{unit}"


def _sampler(s: dict) -> Answer:
    d = s.get("diagnostics", {})
    conv = s.get("convergence", {})
    ok = bool(conv.get("converged", d.get("converged", False)))
    rhat, ess = d.get("max_rhat"), d.get("min_ess")
    nums = []
    if _finite(rhat):
        nums.append(f"max R-hat {float(rhat):.3f} (want < 1.05)")
    if _finite(ess):
        nums.append(f"min effective sample size {float(ess):.0f}")
    if _finite(d.get("n_over_tau")):
        nums.append(f"chain {float(d['n_over_tau']):.0f} autocorrelation times long "
                    "(want > 50)")
    num = ", ".join(nums)
    if ok:
        return Answer("Did the sampler converge?", "ok",
                      f"{num[0].upper() + num[1:]}. The draws describe the posterior of "
                      "this model.")
    problems = "; ".join(conv.get("problems", d.get("problems", [])))
    return Answer("Did the sampler converge?", "bad",
                  f"{problems or num}. Sample longer before using any number below.")


def diagnostic_counts(s: dict) -> tuple[int, int, list[str]]:
    """Residual checks of a run (``summary.json``): how many failed, how many ran, and the
    failed ones' names.

    Parameters
    ----------
    s : dict
        ``summary.json``.

    Returns
    -------
    n_fail, n_all : int
    names : list of str
    """
    n_fail = n_all = 0
    names: list[str] = []
    for r in s.get("crosscheck", {}).get("residuals", []):
        for d in r.get("diagnostics", []):
            if "error" in d:
                continue
            n_all += 1
            if d.get("detected"):
                n_fail += 1
                names.append(d["name"].replace("_", " "))
    return n_fail, n_all, names


def _heldout_records(s: dict) -> list[dict]:
    h = s.get("heldout") or {}
    return list(h.get("records") or [])


def _crossval_records(s: dict) -> list[dict]:
    cv = s.get("crossval") or {}
    return list(cv.get("records") or [])


def _model(s: dict) -> Answer:
    q = "Does the model explain the data?"
    n_fail, n_all, names = diagnostic_counts(s)
    res = s.get("crosscheck", {}).get("residuals", [])
    parts = []
    if res:
        parts.append("fit of the fitted record(s) at the posterior median "
                     + _span([r.get("fit_percent", []) for r in res]))
    held = _heldout_records(s)
    if held:
        parts.append("fit of the held-out record(s) "
                     + _span([r.get("fit_percent", []) for r in held]))
    elif (s.get("heldout") or {}).get("fit_percent_median"):
        parts.append("fit of the held-out record(s) "
                     + _span(s["heldout"]["fit_percent_median"]))
    fits = ("; " + "; ".join(parts)) if parts else ""
    fits += " (100 % would be a perfect fit)" if parts else ""
    if n_all == 0:
        return Answer(q, "unknown", "Not checked: no residual diagnostics in this run"
                      + fits + ".")
    if n_fail == 0:
        return Answer(q, "ok", f"As far as tested: all {n_all} residual checks pass"
                      + fits + ".")
    counts = {nm: names.count(nm) for nm in dict.fromkeys(names)}
    n_rec = len(res)
    listed = ", ".join(nm if c == 1 or n_rec < 2 else f"{nm} ({c} of {n_rec} records)"
                       for nm, c in counts.items())
    return Answer(q, "bad", f"{n_fail} of {n_all} residual checks fail ("
                  + listed + ")" + fits
                  + ". The residuals contain effects the model leaves out.")


def _coverage_phrase(records: list[dict]) -> tuple[str, float | None, float | None]:
    """The coverage span in words, and the smallest and largest coverage (or None)."""
    cov = _flat([r.get("coverage_90", []) for r in records])
    if not cov:
        return "", None, None
    return _span(cov, scale=100.0), min(cov), max(cov)


def _expected_phrase(records: list[dict]) -> str:
    """' (a calibrated band would cover a-b % ...)' from the records' references, or ''."""
    rng = [x for r in records for x in _flat(r.get("coverage_90_expected", []))]
    if not rng:
        return ""
    return (f" (a calibrated band would cover {_span([min(rng), max(rng)], scale=100.0)} "
            "of records like these)")


def _flagged(records: list[dict], prob: float) -> tuple[list[dict], list[dict]]:
    """The records whose band is too narrow, and those whose band is wider than a
    calibrated one (:func:`record_status` over all of them)."""
    st = [record_status(r, len(records), prob) for r in records]
    return ([r for r, x in zip(records, st, strict=True) if x == "narrow"],
            [r for r, x in zip(records, st, strict=True) if x == "wide"])


def _flag_detail(r: dict, status: str) -> str:
    """One flagged record in words, with the numbers that flagged it."""
    name = r.get("name", "?")
    exp = _flat(r.get("coverage_90_expected", []))
    cov = f"covers {_span(r.get('coverage_90', []), scale=100.0)}"
    if exp:
        cov += f" where a calibrated band covers {_span([min(exp), max(exp)], scale=100.0)}"
    fexp = _flat(r.get("band_factor_90_expected", []))
    f = _flat(r.get("band_factor_90", []))
    if status == "narrow" and f and fexp:
        return (f"{name} (its misses lie further out than a calibrated band's: it would "
                f"have to be {_span(f, '.1f', unit='')} times as wide, a calibrated one at "
                f"most {max(fexp):.1f}; {cov})")
    return f"{name} ({cov})"


def _intervals(s: dict, model: Answer, flags: tuple[list[dict], list[dict]]) -> Answer:
    """The third answer; ``flags``: the records whose band is too narrow, and those
    whose band is wider than a calibrated one (``_flagged``)."""
    q = "How far can the intervals be trusted?"
    prob = float(s.get("prob", 0.9))
    pct = f"{100 * prob:.0f} %"
    parts = [f"The {pct} intervals below are conditional on this model: they give the "
             "spread of the parameters if the model were right"]
    if model.status == "bad":
        parts[0] += ", and it is not"
    lsq = s.get("lsq_comparison") or []
    if lsq:
        params = s.get("parameters", {})
        n_par = [r for r in lsq if r["quantity"] in params]
        out_all = sum(1 for r in lsq if not r["inside"])
        out_par = sum(1 for r in n_par if not r["inside"])
        parts.append(f"{out_par} of {len(n_par)} least-squares parameter values "
                     f"(and {out_all} of {len(lsq)} values including modal quantities) "
                     f"lie outside them")
    lsce = [c for c in s.get("crosscheck", {}).get("lsce", []) if not c.get("error")]
    if lsce:
        n_in = n_tot = 0
        for c in lsce:
            for key, col in (("omega_rad_s", "omega_matched"), ("zeta", "zeta_matched")):
                iv = s.get(key, {})
                for i, v in enumerate(c.get(col, [])):
                    if not _finite(v) or i >= len(iv.get("lo", [])):
                        continue
                    n_tot += 1
                    n_in += iv["lo"][i] <= float(v) <= iv["hi"][i]
        if n_tot:
            parts.append(f"{n_tot - n_in} of {n_tot} model-free LSCE estimates of "
                         "frequency and damping lie outside them")
    held, cvr = _heldout_records(s), _crossval_records(s)
    held_txt, _, _ = _coverage_phrase(held)
    cv_txt, _, _ = _coverage_phrase(cvr)
    if held_txt:
        parts.append(f"the {pct} predictive band covers {held_txt} of the held-out "
                     "record(s)" + _expected_phrase(held))
    if cv_txt:
        parts.append(f"leaving one record out, the {pct} band covers {cv_txt} of the "
                     "left-out record" + _expected_phrase(cvr))
    narrow, wide = flags
    if narrow:
        parts.append("it is too narrow for " + "; ".join(_flag_detail(r, "narrow")
                                                        for r in narrow))
    if wide:
        parts.append("it is wider than a calibrated band for " + "; ".join(
            _flag_detail(r, "wide") for r in wide))
    if model.status == "bad" or narrow:
        status = "bad"
    elif model.status == "unknown" or not (held or cvr):
        status = "unknown"
    else:
        status = "ok"
    text = parts[0] + ". " + ("; ".join(parts[1:]) + "." if len(parts) > 1 else "")
    text = text[0].upper() + text[1:]
    if status == "bad":
        text += (" Read them as a lower bound on the uncertainty, not as error bars of the "
                 "rig's parameters.")
    elif status == "unknown":
        text += (" Nothing here tests them on data the model was not fitted to; add "
                 "held-out records to check.")
    return Answer(q, status, text.strip())


def run_verdict(summary: dict) -> RunVerdict:
    """The three first-screen answers and the overall sentence of a run.

    Parameters
    ----------
    summary : dict
        Content of ``summary.json``; uses ``convergence``/``diagnostics``,
        ``crosscheck.residuals[].diagnostics`` and ``fit_percent``, ``lsq_comparison``,
        ``crosscheck.lsce``, ``heldout.records[].coverage_90`` and, when present,
        ``crossval.records[].coverage_90``.  Missing parts give ``"unknown"`` answers.

    Returns
    -------
    RunVerdict

    Examples
    --------
    >>> v = run_verdict({"diagnostics": {"converged": True, "max_rhat": 1.01,
    ...                                  "min_ess": 900}})
    >>> v.sampler.status, v.ok
    ('ok', False)
    """
    a = _sampler(summary)
    b = _model(summary)
    prob = float(summary.get("prob", 0.9))
    flags = _flagged(_heldout_records(summary) + _crossval_records(summary), prob)
    c = _intervals(summary, b, flags)
    pct = f"{100 * prob:.0f} %"
    held_txt, _, _ = _coverage_phrase(_heldout_records(summary))
    cv_txt, _, _ = _coverage_phrase(_crossval_records(summary))
    cov_txt = ""
    if held_txt:
        cov_txt = f"held-out {pct} band covers {held_txt}"
    elif cv_txt:
        cov_txt = f"left-out {pct} band covers {cv_txt}"
    first = ("The sampler converged" if a.status == "ok"
             else "The sampler has NOT converged (sample longer)")
    if b.status == "bad":
        n_fail, n_all, _ = diagnostic_counts(summary)
        second = (f"the model does not explain the data: {n_fail} of {n_all} residual "
                  "checks fail")
        joint = ", but " if a.status == "ok" else ", and "
    elif b.status == "ok":
        second = "the model passes its residual checks"
        joint = " and " if a.status == "ok" else ", although "
    else:
        second = "the residuals were not checked"
        joint = "; "
    narrow, wide = bool(flags[0]), bool(flags[1])
    if c.status == "bad":
        third = "the intervals below are conditional on this model"
        if narrow and wide:
            third += (" and their predictive band is too narrow for some records and wider "
                      f"than needed on others ({cov_txt})")
        elif narrow:
            third += f" and are too narrow for the next record ({cov_txt})"
        elif wide:
            third += (" and their predictive band reaches its coverage only by being wider "
                      f"than needed ({cov_txt})")
        else:
            third += " and understate the uncertainty"
    elif c.status == "ok" and wide:
        third = (f"the intervals below hold on new data, with a predictive band wider than "
                 f"needed ({cov_txt})")
    elif c.status == "ok":
        third = f"the intervals below hold on new data ({cov_txt})"
    else:
        third = ("the intervals below are conditional on this model and untested on "
                 "new data")
    sentence = f"{first}{joint}{second}; {third}."
    return RunVerdict(a, b, c, sentence, all(x.status == "ok" for x in (a, b, c)))
