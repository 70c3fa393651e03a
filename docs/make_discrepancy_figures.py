"""Compute every number and figure of docs/discrepancy.md from the measured ECP data.

Run from the repository root (the measured data are found as everywhere, through
``bayesmodal.data.find_data``)::

    python docs/make_discrepancy_figures.py            # figures + docs/figures/discrepancy.json
    python docs/make_discrepancy_figures.py --quick    # skip the two posterior runs

The two posterior runs are the shipped configurations ``runs/impulses_free.toml`` and
``runs/impulses_friction.toml``, sampled with ``bayesmodal.runs.run_config`` into
``out/discrepancy_runs/`` (resumed if already there).  Everything else is least squares
and the residual diagnostics.  Wall time: about 10 minutes for the least-squares part and
20 for the posterior runs on two cores.

``tests/test_discrepancy_story.py`` re-checks the key claims.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from bayesmodal.data import find_data, load_experiment
from bayesmodal.discrepancy.checks import RESIDUAL_DIAGNOSTICS, linear_residuals
from bayesmodal.fit import fit_extension_lsq, fit_lsq
from bayesmodal.fit.effects import extension_residuals
from bayesmodal.metrics import fit_percent
from bayesmodal.model.effects import EXTENSIONS
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

ROOT = Path(__file__).resolve().parents[1]
RECORDS = ("data_impulses", "data_steps", "data_sine_sweep_fast", "data_sine_sweep_slow")
SHORT = {"data_impulses": "impulses", "data_steps": "steps",
         "data_sine_sweep_fast": "sweep fast", "data_sine_sweep_slow": "sweep slow"}
RIG = Rig()
MODEL = LinearModel(RIG, "free")
FRICTION = EXTENSIONS["coulomb_friction"]


def load_records() -> dict:
    """The four measured records, or raise FileNotFoundError naming the missing one."""
    out = {}
    for name in RECORDS:
        p = find_data(f"ecp210-3dof/{name}.mat")
        if p is None:
            raise FileNotFoundError(f"measured record {name}.mat not found (see "
                                    "bayesmodal.data.data_root)")
        out[name] = load_experiment(p)
    return out


def predict(theta: np.ndarray, e, extension=None) -> np.ndarray:
    """Noise-free prediction of one record, m."""
    if extension is None:
        return simulate_linear(MODEL, theta, e.v_volt, e.dt)
    return extension.simulate(RIG, theta, e.v_volt, e.dt)


def fits_on(theta, recs: dict, extension=None) -> dict:
    """Fit percent per record and cart, rounded to 0.1."""
    return {n: np.round(fit_percent(e.y_m, predict(theta, e, extension)), 1).tolist()
            for n, e in recs.items()}


def mean_fit(fits: dict, name: str) -> float:
    return float(np.mean(fits[name]))


# ----------------------------------------------------------------------------- steps
def linear_part(recs: dict) -> dict:
    """Linear free-damping fit on the impulses and its predictions."""
    lin = fit_lsq(recs["data_impulses"], MODEL)
    return {"theta": lin.theta.tolist(), "names": list(MODEL.names),
            "fits": fits_on(lin.theta, recs), "_lsq": lin}


def diagnostics_part(recs: dict, theta_lin) -> dict:
    """Every single-record residual diagnostic on the impulse residuals of the linear fit."""
    res = linear_residuals(recs["data_impulses"], MODEL, np.asarray(theta_lin))
    out = {}
    for name, fn in RESIDUAL_DIAGNOSTICS.items():
        d = fn(res)
        out[name] = {"statistic": float(d.statistic),
                     "p_value": None if d.p_value is None else float(d.p_value),
                     "threshold": None if d.threshold is None else float(d.threshold),
                     "detected": bool(d.detected), "suggests": list(d.suggests),
                     "location": d.location, "summary": d.summary, "_result": d}
    out["_residuals"] = res
    return out


def friction_part(recs: dict, lin_lsq, **options) -> dict:
    """Friction fitted on the impulses by least squares and its predictions (``options``
    go to ``fit_extension_lsq``: the default single start, or a multi-start)."""
    fit = fit_extension_lsq(recs["data_impulses"], FRICTION, RIG, linear=lin_lsq, **options)
    return {"theta": fit.theta.tolist(), "names": list(fit.names), "cost": fit.cost,
            "fits": fits_on(fit.theta, recs, FRICTION), "_fit": fit}


def basins_part(recs: dict, lin_lsq, n: int = 6) -> list:
    """Local least-squares optima of the friction model on the impulses, from the ``n``
    best start candidates of ``fit_extension_lsq`` (grid x damper scales), each with its
    impulse cost and its predictions of the held-out records."""
    imp = recs["data_impulses"]
    grid = FRICTION.start_grid(RIG)
    lin_starts = []
    for f in (1.0, 0.3, 0.1):
        th = np.array(lin_lsq.theta)
        th[1 + RIG.n_carts :] *= f
        lin_starts.append(th)
    cands = np.concatenate([np.repeat(lin_starts, len(grid), axis=0),
                            np.tile(grid, (len(lin_starts), 1))], axis=1)
    cands = cands[FRICTION.valid(RIG, cands)]
    r = extension_residuals(FRICTION, RIG, cands, [imp])
    order = np.argsort(np.sum(r**2, axis=1))[:n]
    out = []
    for i in order:
        fit = fit_extension_lsq(imp, FRICTION, RIG, theta0=cands[i], linear=lin_lsq)
        out.append({"start": cands[i].tolist(), "theta": fit.theta.tolist(),
                    "cost": fit.cost, "fits": fits_on(fit.theta, recs, FRICTION)})
    out.sort(key=lambda b: b["cost"])
    return out


def other_extensions_part(recs: dict, lin_lsq) -> dict:
    """Every other extension fitted on the impulses: in-sample and held-out fits."""
    out = {}
    for name, ext in EXTENSIONS.items():
        if name == "coulomb_friction":
            continue
        fit = fit_extension_lsq(recs["data_impulses"], ext, RIG, linear=lin_lsq)
        own = ext.extension_names(RIG)
        out[name] = {"params": {k: v for k, v in fit.params.items() if k in own},
                     "fits": fits_on(fit.theta, recs, ext)}
    return out


def per_record_part(recs: dict) -> dict:
    """Linear and friction models fitted to each record on its own (in-sample): the
    drive gain each record asks for, and how much of each record friction can explain."""
    out = {}
    for name in RECORDS:
        e = recs[name]
        lin = fit_lsq(e, MODEL)
        fr = fit_extension_lsq(e, FRICTION, RIG, linear=lin)
        out[name] = {"linear_theta": lin.theta.tolist(), "friction_theta": fr.theta.tolist(),
                     "linear_fit": np.round(lin.fit_percent[0], 1).tolist(),
                     "friction_fit": np.round(fr.fit_percent[0], 1).tolist(),
                     "peak_volt": float(np.max(np.abs(e.v_volt)))}
    return out


def static_gain_part(recs: dict) -> dict:
    """Drive gain from the step plateaus: the carts at rest 0.8-1.0 s before each switch,
    ``g_v = x_i / (v * compliance_i)`` with the series compliance from cart i to the
    frame (springs fixed at 774, 770, 396 N/m)."""
    e = recs["data_steps"]
    k = np.asarray(RIG.springs_n_m, float)
    comp = np.array([1 / k[0] + 1 / k[1] + 1 / k[2], 1 / k[1] + 1 / k[2], 1 / k[2]])
    switches = np.nonzero(np.diff(e.v_volt))[0] + 1
    on, off = [], []
    for s in switches:
        seg = slice(max(s - 200, 0), s - 5)
        v = float(np.mean(e.v_volt[seg]))
        x = np.mean(e.y_m[seg], axis=0)
        if v > 0.45:
            on.append(x / (v * comp))
        elif abs(v) < 1e-9:
            off.append(x)
    on = np.array(on)
    return {"g_v_per_cart_mean": on.mean(axis=0).tolist(),
            "g_v_min": float(on.min()), "g_v_max": float(on.max()),
            "n_plateaus": int(on.shape[0]),
            "off_position_range_counts": (np.ptp(np.array(off), axis=0)
                                          / 4.4125e-6).round(1).tolist()}


def spectrum_part(recs: dict, theta, extension) -> dict:
    """Largest peaks of the residual spectrum of each record under a model, Hz."""
    from scipy.signal import welch

    out = {}
    for name, e in recs.items():
        r = e.y_m - predict(theta, e, extension)
        f, p = welch(r, fs=1 / e.dt, nperseg=1024, axis=0)
        tot = p.sum(axis=1)
        band = f > 0.3
        i = np.argmax(tot[band])
        out[name] = {"peak_hz": float(f[band][i]),
                     "share_below_10hz": float(tot[f < 10].sum() / tot.sum())}
    return out


# ----------------------------------------------------------------------------- posterior
def _summary_of(idata, prob: float = 0.9) -> dict:
    from bayesmodal.inference import parameter_intervals

    return {k: {"median": iv.median, "lo": iv.lo, "hi": iv.hi}
            for k, iv in parameter_intervals(idata, prob).items()}


def posterior_part(recs: dict, runs_dir: Path) -> dict:
    """Posterior runs on the impulses: the shipped linear and friction configurations.

    The friction run (``runs/impulses_friction.toml``) re-centres its ensemble once on the
    best walker during burn-in (``[sampler] restart``): the static levels ``Fs`` can
    leave walkers in separated modes of negligible mass.  Intervals, the ELPD change and
    the held-out scores come from the two runs as shipped.
    """
    from bayesmodal.inference import (
        elpd_change,
        likelihood_from_idata,
        load_idata,
        posterior_matrix,
        predictive_check,
    )
    from bayesmodal.runs import run_config

    out: dict = {}
    idatas = {}
    for label, cfg in (("linear", "impulses_free"), ("friction", "impulses_friction")):
        folder = runs_dir / cfg
        res = run_config(ROOT / "runs" / f"{cfg}.toml", folder, resume=True)
        idatas[label] = load_idata(folder / "posterior.nc")
        out[label] = {"converged": bool(res.summary["convergence"]["converged"]),
                      "convergence": res.summary["convergence"]["verdict"]}
    diag = json.loads(idatas["friction"].posterior.attrs["diagnostics_json"])
    out["friction"].update({"max_rhat": diag["max_rhat"], "min_ess": diag["min_ess"],
                            "n_over_tau": diag["n_over_tau"], "problems": diag["problems"]})
    for label in ("linear", "friction"):
        out[label]["parameters"] = _summary_of(idatas[label])
        lik = likelihood_from_idata(idatas[label])
        med = np.array([out[label]["parameters"][n]["median"] for n in lik.mech_names])
        out[label]["fits_at_median"] = fits_on(med, recs,
                                               FRICTION if label == "friction" else None)
    ch = elpd_change(idatas["linear"], idatas["friction"], labels=("linear", "friction"))
    out["elpd"] = ch.as_dict()
    held = {}
    for label in ("linear", "friction"):
        idt = idatas[label]
        held[label] = {}
        for name in RECORDS[1:]:
            lik = likelihood_from_idata(idt, [recs[name]])
            draws = posterior_matrix(idt, list(lik.names)).reshape(-1, lik.n_params)
            ps = predictive_check(lik, draws, max_draws=100)
            held[label][name] = {"fit_median": np.round(ps.fit_percent_median[0], 1).tolist(),
                                 "fit_lo": np.round(ps.fit_percent_lo[0], 1).tolist(),
                                 "fit_hi": np.round(ps.fit_percent_hi[0], 1).tolist(),
                                 "lpd": ps.lpd}
    out["heldout"] = held
    out["_idata"] = idatas
    return out


def numerics_part(recs: dict, theta: np.ndarray) -> dict:
    """The friction fit at ``theta`` on the impulses with 1 to 16 sub-steps per sample and
    with the independent event-driven reference simulator of ``tests/reference_sim.py``."""
    from bayesmodal.model.effects import CoulombFriction

    e = recs["data_impulses"]
    out = {f"n_sub_{k}": np.round(fit_percent(
        e.y_m, CoulombFriction(n_sub=k).simulate(RIG, theta, e.v_volt, e.dt)), 2).tolist()
        for k in (1, 2, 4, 8, 16)}
    sys.path.insert(0, str(ROOT / "tests"))
    try:
        from reference_sim import simulate_coulomb_ref
    finally:
        sys.path.pop(0)
    y = simulate_coulomb_ref(RIG.springs_n_m, theta, e.v_volt, e.dt)
    out["reference"] = np.round(fit_percent(e.y_m, y), 2).tolist()
    return out


def gain_counterfactual_part(recs: dict, theta: np.ndarray) -> dict:
    """How much of each held-out misfit the drive gain alone explains: every parameter at
    ``theta`` (the friction posterior median on the impulses) except ``g_v``, refitted to
    the record by a one-dimensional least-squares search."""
    from scipy.optimize import minimize_scalar

    out = {}
    for name in RECORDS[1:]:
        e = recs[name]

        def cost(gv, e=e):
            th = np.array(theta, dtype=float)
            th[0] = gv
            return float(np.sum((e.y_m - predict(th, e, FRICTION)) ** 2))

        res = minimize_scalar(cost, bounds=(3.0, 8.0), method="bounded",
                              options={"xatol": 1e-3})
        th = np.array(theta, dtype=float)
        th[0] = res.x
        out[name] = {"g_v": float(res.x),
                     "fit": np.round(fit_percent(e.y_m, predict(th, e, FRICTION)), 1).tolist()}
    return out


#: Weights of the held-out step record in the trade-off fits (the impulses weigh 1).
TRADEOFF_WEIGHTS = (0.0, 0.01, 0.03, 0.1, 0.3, 1.0)


def _profile_loglik(r: np.ndarray) -> dict:
    """Log-likelihood of residuals ``r`` (N, n_out), m, maximised over the noise
    parameters of each output: white Gaussian (sigma) and AR(1) (phi, sigma), nats."""
    from bayesmodal.inference.likelihood import ar1_terms

    n = r.shape[0]
    sig_w = np.sqrt(np.mean(r**2, axis=0))
    white = float(np.sum(-0.5 * n * (np.log(2 * np.pi * sig_w**2) + 1.0)))
    phi = np.clip(np.sum(r[1:] * r[:-1], axis=0) / np.sum(r[:-1] ** 2, axis=0), -0.9999, 0.9999)
    sig = np.sqrt(np.mean((r[1:] - phi * r[:-1]) ** 2, axis=0))
    ar1 = float(np.sum(ar1_terms(r[None], sig[None], phi[None])))
    return {"white": white, "ar1": ar1, "phi": phi.tolist()}


def tradeoff_part(recs: dict, lin_lsq, theta0) -> list:
    """How far the step record can pull the friction fit before the impulse fit degrades:
    least squares on the impulses and the steps with the steps weighted by each of
    ``TRADEOFF_WEIGHTS`` (``fit_extension_lsq(weights=...)``), all started from the
    single-start impulse optimum ``theta0``; each point's fit of every record and its
    impulse log-likelihood maximised over white and AR(1) noise."""
    imp, steps = recs["data_impulses"], recs["data_steps"]
    out = []
    for lam in TRADEOFF_WEIGHTS:
        fit = fit_extension_lsq([imp, steps], FRICTION, RIG, theta0=theta0, linear=lin_lsq,
                                weights=(1.0, lam))
        r = imp.y_m - predict(fit.theta, imp, FRICTION)
        out.append({"weight_steps": lam, "theta": fit.theta.tolist(),
                    "impulse_cost": 0.5 * float(np.sum(r**2)),
                    "impulse_loglik": _profile_loglik(r),
                    "fits": fits_on(fit.theta, recs, FRICTION)})
    return out


def loglik_references(recs: dict, num: dict) -> dict:
    """Impulse log-likelihoods (``_profile_loglik``) and fits of the linear and friction
    least-squares estimates and of the friction posterior median, beside the trade-off."""
    imp = recs["data_impulses"]
    thetas = {"linear_lsq": (np.asarray(num["linear"]["theta"]), None),
              "friction_lsq": (np.asarray(num["friction"]["theta"]), FRICTION)}
    if num.get("posterior"):
        med = num["posterior"]["friction"]["parameters"]
        thetas["friction_posterior_median"] = (
            np.array([med[n]["median"] for n in FRICTION.names(RIG)]), FRICTION)
    return {label: {"impulse_loglik": _profile_loglik(imp.y_m - predict(th, imp, ext)),
                    "fits": fits_on(th, recs, ext)}
            for label, (th, ext) in thetas.items()}


def tradeoff_figure(recs: dict, num: dict, out: Path) -> str:
    """Impulse fit against the held-out fits along the trade-off."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts = num["tradeoff"]
    x = [mean_fit(p["fits"], "data_impulses") for p in pts]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name, mark in (("data_steps", "o-"), ("data_sine_sweep_fast", "s--"),
                       ("data_sine_sweep_slow", "^--")):
        ax.plot(x, [mean_fit(p["fits"], name) for p in pts], mark, label=SHORT[name])
        ax.axhline(mean_fit(num["linear"]["fits"], name), color="0.7", lw=0.8)
    for p, xi in zip(pts, x, strict=True):
        ax.annotate(f"{p['weight_steps']:g}", (xi, mean_fit(p["fits"], "data_steps")),
                    textcoords="offset points", xytext=(4, 4), fontsize=8)
    ax.set_xlabel("fit on the impulses, % (mean over carts)")
    ax.set_ylabel("fit of the other records, %")
    ax.set_title("friction fits: impulses + steps weighted by the labelled factor\n"
                 "(grey: the linear model fitted on the impulses)")
    ax.invert_xaxis()
    ax.legend()
    _save(fig, out / "discrepancy_tradeoff.png")
    return "discrepancy_tradeoff.png"


# ----------------------------------------------------------------------------- figures
def _save(fig, path: Path) -> None:
    import matplotlib.pyplot as plt

    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)


def figures(recs: dict, num: dict, objs: dict, out: Path) -> list[str]:
    """Write the tutorial's figures; returns their file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bayesmodal.plots.diagnostics import plot_diagnostic

    made = []
    q = 4.4125e-6  # m per encoder count
    lin = np.asarray(num["linear"]["theta"])
    post = num.get("posterior")
    if post:  # the posterior median of the friction model on the impulses
        fr_names = FRICTION.names(RIG)
        fr = np.array([post["friction"]["parameters"][n]["median"] for n in fr_names])
        fr_fits = post["friction"]["fits_at_median"]
        fr_label = "friction, posterior median"
    else:
        fr = np.asarray(num["friction"]["theta"])
        fr_fits = num["friction"]["fits"]
        fr_label = "friction, least squares"

    # 1. linear misfit and the friction fit on the impulses (first pulse), and held out
    for name, fname, t_max in (("data_impulses", "discrepancy_impulses.png", 10.0),
                               ("data_steps", "discrepancy_steps.png", 20.0),
                               ("data_sine_sweep_fast", "discrepancy_sweep.png", 36.5)):
        e = recs[name]
        sel = e.t_s <= t_max
        fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
        yl, yf = predict(lin, e), predict(fr, e, FRICTION)
        for j, ax in enumerate(axes):
            ax.plot(e.t_s[sel], e.y_m[sel, j] / q, "k", lw=1.2, label="measured")
            ax.plot(e.t_s[sel], yl[sel, j] / q, "C0", lw=0.9,
                    label=f"linear ({num['linear']['fits'][name][j]:.1f} %)")
            ax.plot(e.t_s[sel], yf[sel, j] / q, "C3", lw=0.9,
                    label=f"{fr_label} ({fr_fits[name][j]:.1f} %)")
            ax.set_ylabel(f"x{j + 1} (counts)")
            ax.legend(loc="upper right", fontsize=8)
        axes[-1].set_xlabel("t (s)")
        role = "fitted" if name == "data_impulses" else "held out"
        axes[0].set_title(f"{SHORT[name]} ({role}): parameters fitted on the impulses")
        _save(fig, out / fname)
        made.append(fname)

    # 2. the diagnostics that point at friction
    diag = objs["diagnostics"]
    shown = [n for n in ("friction_signature", "decay_envelope", "stick", "residual_spectrum")
             if n in diag]
    fig, axes = plt.subplots(2, 2, figsize=(11, 7))
    for ax, n in zip(axes.ravel(), shown, strict=False):
        plot_diagnostic(diag[n]["_result"], ax=ax)
    fig.tight_layout()
    _save(fig, out / "discrepancy_diagnostics.png")
    made.append("discrepancy_diagnostics.png")

    # 3. basins: impulse cost against held-out fits
    b = num["basins"]
    fig, ax = plt.subplots(figsize=(6.5, 4))
    cost = np.array([x["cost"] for x in b])
    for name, mk in (("data_steps", "o"), ("data_sine_sweep_fast", "s"),
                     ("data_sine_sweep_slow", "^")):
        ax.plot(cost * 1e3, [mean_fit(x["fits"], name) for x in b], mk, label=SHORT[name])
    ax.set_xlabel("impulse cost (half sum of squares), 1e-3 m^2")
    ax.set_ylabel("held-out fit (mean over carts), %")
    ax.set_title("local optima of the friction fit on the impulses")
    ax.legend()
    _save(fig, out / "discrepancy_basins.png")
    made.append("discrepancy_basins.png")

    # 4. posterior intervals: dampers of both runs and friction levels
    if post:
        fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
        names = ["c1", "c2", "c3", "c12", "c23"]
        for k, (label, col) in enumerate((("linear", "C0"), ("friction", "C3"))):
            p = post[label]["parameters"]
            x = np.arange(len(names)) + (k - 0.5) * 0.25
            med = np.array([p[n]["median"] for n in names])
            lo = np.array([p[n]["lo"] for n in names])
            hi = np.array([p[n]["hi"] for n in names])
            axes[0].errorbar(x, med, yerr=[med - lo, hi - med], fmt="o", color=col,
                             label=label, capsize=3)
        axes[0].set_xticks(range(len(names)), names)
        axes[0].set_ylabel("damping (N s/m), median and 90 % interval")
        axes[0].legend()
        p = post["friction"]["parameters"]
        fnames = ["Fc1", "Fc2", "Fc3", "Fs1", "Fs2", "Fs3"]
        med = np.array([p[n]["median"] for n in fnames])
        lo = np.array([p[n]["lo"] for n in fnames])
        hi = np.array([p[n]["hi"] for n in fnames])
        axes[1].errorbar(range(6), med, yerr=[med - lo, hi - med], fmt="o", color="C3",
                         capsize=3)
        axes[1].set_xticks(range(6), fnames)
        axes[1].set_ylabel("friction force (N), median and 90 % interval")
        fig.tight_layout()
        _save(fig, out / "discrepancy_posterior.png")
        made.append("discrepancy_posterior.png")

    # 5. drive gain asked for by each record
    per = num["per_record"]
    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    xs = np.arange(len(RECORDS))
    ax.bar(xs - 0.2, [per[n]["linear_theta"][0] for n in RECORDS], 0.4, label="linear fit")
    ax.bar(xs + 0.2, [per[n]["friction_theta"][0] for n in RECORDS], 0.4,
           label="friction fit")
    sg = num["static_gain"]
    ax.axhspan(sg["g_v_min"], sg["g_v_max"], color="0.8", label="step plateaus (static)")
    ax.set_xticks(xs, [f"{SHORT[n]}\n{per[n]['peak_volt']:.1f} V" for n in RECORDS])
    ax.set_ylabel("g_v (N/V)")
    ax.set_ylim(3.5, 7)
    ax.legend(fontsize=8)
    ax.set_title("drive gain fitted to each record on its own")
    _save(fig, out / "discrepancy_gain.png")
    made.append("discrepancy_gain.png")
    if "tradeoff" in num:
        made.append(tradeoff_figure(recs, num, out))
    return made


# ----------------------------------------------------------------------------- main
def _public(d):
    """Drop the private (``_``-prefixed) objects before writing JSON."""
    if isinstance(d, dict):
        return {k: _public(v) for k, v in d.items() if not str(k).startswith("_")}
    if isinstance(d, list):
        return [_public(v) for v in d]
    return d


def compute(*, runs_dir: Path | None, log=print) -> tuple[dict, dict]:
    """All numbers of the tutorial (JSON-ready) and the objects the figures need."""
    recs = load_records()
    t0 = time.perf_counter()
    num: dict = {}
    objs: dict = {}
    lin = linear_part(recs)
    num["linear"] = lin
    log(f"linear fit done ({time.perf_counter() - t0:.0f} s)")
    objs["diagnostics"] = diagnostics_part(recs, lin["theta"])
    num["diagnostics"] = objs["diagnostics"]
    log(f"diagnostics done ({time.perf_counter() - t0:.0f} s)")
    num["friction"] = friction_part(recs, lin["_lsq"])
    num["friction_multistart"] = friction_part(recs, lin["_lsq"], n_starts=3,
                                               damper_scales=(1.0, 0.3, 0.1))
    log(f"friction fits done ({time.perf_counter() - t0:.0f} s)")
    num["basins"] = basins_part(recs, lin["_lsq"])
    log(f"basins done ({time.perf_counter() - t0:.0f} s)")
    num["numerics"] = numerics_part(recs, np.asarray(num["friction"]["theta"]))
    num["tradeoff"] = tradeoff_part(recs, lin["_lsq"], np.asarray(num["friction"]["theta"]))
    log(f"trade-off fits done ({time.perf_counter() - t0:.0f} s)")
    num["static_gain"] = static_gain_part(recs)
    num["per_record"] = per_record_part(recs)
    log(f"per-record fits done ({time.perf_counter() - t0:.0f} s)")
    num["other_extensions"] = other_extensions_part(recs, lin["_lsq"])
    log(f"other extensions done ({time.perf_counter() - t0:.0f} s)")
    num["spectrum_linear"] = spectrum_part(recs, np.asarray(lin["theta"]), None)
    num["spectrum_friction"] = spectrum_part(recs, np.asarray(num["friction"]["theta"]),
                                             FRICTION)
    if runs_dir is not None:
        num["posterior"] = posterior_part(recs, runs_dir)
        log(f"posterior runs done ({time.perf_counter() - t0:.0f} s)")
        med = num["posterior"]["friction"]["parameters"]
        theta = np.array([med[n]["median"] for n in FRICTION.names(RIG)])
        num["gain_counterfactual"] = gain_counterfactual_part(recs, theta)
    num["loglik_references"] = loglik_references(recs, num)
    return num, objs


def table(num: dict) -> str:
    """The stored result as the Markdown table the script prints: the fit (%) of each
    record's carts 1-3 with the impulse record's least-squares fits (linear, stick-slip
    friction, and each other effect of the catalogue)."""
    short = ("impulses", "steps", "sweep fast", "sweep slow")
    lines = ["| model fitted to the impulses | " + " | ".join(short) + " |",
             "|---" * (len(short) + 1) + "|"]
    rows = {"linear": num["linear"]["fits"], "stick-slip friction": num["friction"]["fits"]}
    rows.update({name: r["fits"] for name, r in num["other_extensions"].items()})
    for label, fits in rows.items():
        cells = " | ".join(", ".join(f"{x:.1f}" for x in fits[n]) for n in RECORDS)
        lines.append(f"| {label} | {cells} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    from _stamp import stamp  # docs/_stamp.py (run as docs/<script>.py)

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures"))
    ap.add_argument("--runs", default=str(ROOT / "out" / "discrepancy_runs"))
    ap.add_argument("--quick", action="store_true", help="skip the posterior runs")
    ap.add_argument("--tradeoff-only", action="store_true",
                    help="recompute only the trade-off fits and the log-likelihood references "
                    "(section 5) into the existing discrepancy.json, from its estimates")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if args.tradeoff_only:
        path = out / "discrepancy.json"
        num = json.loads(path.read_text())
        recs = load_records()
        lin = fit_lsq(recs["data_impulses"], MODEL)
        if not np.allclose(lin.theta, num["linear"]["theta"], rtol=1e-6):
            raise SystemExit("the linear fit differs from discrepancy.json: run the whole "
                             "script")
        num["tradeoff"] = _public(tradeoff_part(recs, lin, np.asarray(num["friction"]["theta"])))
        num["loglik_references"] = loglik_references(recs, num)
        made = tradeoff_figure(recs, num, out)
        num["stamp_tradeoff"] = stamp()
        path.write_text(json.dumps(num, indent=1, default=float) + "\n")
        print(f"wrote {made} and the trade-off into {path}")
        return 0
    num, objs = compute(runs_dir=None if args.quick else Path(args.runs),
                        log=lambda m: print(m, file=sys.stderr, flush=True))
    made = figures(load_records(), num, objs, out)
    public = {**_public(num), "stamp": stamp()}
    (out / "discrepancy.json").write_text(json.dumps(public, indent=1, default=float) + "\n")
    print(table(public))
    print(f"wrote {', '.join(made)} and discrepancy.json to {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
