"""ArviZ InferenceData assembly and NetCDF I/O (the only module that builds ArviZ objects).

Groups written by :func:`to_inference_data`:

``posterior``
    One variable per parameter (``g_v``, ``m1``, ..., ``sigma_1``, ``phi_1``, ...), physical
    units, dims ``(chain, draw)``; walkers are chains, draws are the retained steps.
``sample_stats``
    ``lp`` (log posterior of the sampling coordinates, up to a constant) and
    ``total_log_likelihood``, dims ``(chain, draw)``.
``log_likelihood``
    ``y``: pointwise terms, dims ``(chain, draw, obs, output)`` (see ``likelihood``); the
    ``obs`` dimension runs over the samples of all experiments, with coordinates
    ``experiment`` and ``t_s``.  Stored as float32 (with some 20 000 observations and
    1000 draws it is the bulk of the file); PSIS-LOO and WAIC from float32 and float64
    terms agree to better than 1e-6 relative on the rig data.  It can be left out
    (``pointwise=False``) and rebuilt later, bit for bit, from the posterior draws and the
    observed data with :func:`with_pointwise_loglik`.
``posterior_predictive``
    ``y`` (replicated measurements: model output plus a draw of the noise model) and
    ``y_hat`` (noise-free model output), dims ``(chain, draw, obs, output)``, for at most
    ``n_predictive`` draws (:func:`predictive_subset`), float32; the file stores them as
    integer multiples of :func:`predictive_quantum` (1e-4 of the smallest output's
    standard deviation, 1e-7 m on the rig records: 1/44 of an encoder count).
``observed_data``
    ``y``, dims ``(obs, output)``, m.
``constant_data``
    ``v_volt``, dims ``(obs,)``, the motor voltage.

Attributes (every group): package version, configuration hash and JSON, the least-squares
estimate, noise model, damping model, model extension (``extension``, empty for the linear
model; ``mechanical_names`` then lists the linear and the extension parameters), sampling
time and data hashes.  The modal quantities of a run with an extension are those of its
linear part (:func:`model_from_idata` is always the linear model).
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import numpy as np

from .._errors import DataError
from .._version import __version__
from ..data import Experiment
from ..model.effects import get_extension
from ..model.rigs import rig_from_toml, rig_to_toml
from ..model.system import LinearModel, Rig
from .likelihood import Likelihood
from .priors import PriorSet
from .record_layout import RecordLayout
from .record_scale import RecordScales

__all__ = [
    "arviz",
    "to_inference_data",
    "save_idata",
    "load_idata",
    "with_pointwise_loglik",
    "posterior_matrix",
    "model_from_idata",
    "extension_from_idata",
    "priors_from_idata",
    "experiments_from_idata",
    "likelihood_from_idata",
]


def arviz():
    """Import ArviZ 0.x without its once-a-day refactor announcement.

    ArviZ 0.23 emits a ``FutureWarning`` about its 1.x refactor on the first import of the
    day; it says nothing about this package's use of the 0.x API, so it is silenced here,
    locally, and no other warning is touched.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"\s*ArviZ is undergoing a major refactor",
                                category=FutureWarning)
        import arviz as az
    return az


def _obs_coords(experiments) -> dict:
    names = np.concatenate([[e.name] * e.n_samples for e in experiments])
    t = np.concatenate([e.t_s for e in experiments])
    return {
        "obs": np.arange(t.size),
        "experiment": ("obs", names.astype(str)),
        "t_s": ("obs", t),
        "output": [f"x{j + 1}" for j in range(experiments[0].n_outputs)],
    }


def _attrs(run) -> dict:
    import emcee


    lik = run.likelihood
    attrs = {
        "inference_library": "emcee",
        "inference_library_version": emcee.__version__,
        "bayesmodal_version": __version__,
        "config_hash": run.config_hash,
        "config_json": json.dumps(run.config, sort_keys=True, default=str),
        "damping": lik.model.damping,
        "noise": lik.noise,
        "extension": lik.extension_name or "",
        "parameter_names": json.dumps(list(run.names)),
        "mechanical_names": json.dumps(list(lik.mech_names)),
        "springs_n_m": json.dumps(list(lik.model.rig.springs_n_m)),
        **({} if lik.model.rig.is_chain else {"rig_toml": _rig_toml(lik.model.rig)}),
        **({} if lik.initial_state == "rest" else {"initial_state": lik.initial_state}),
        "burn": int(run.burn),
        "thin": int(run.thin),
        "n_steps": int(run.chain.shape[0]),
        "sampling_time_s": float(run.elapsed_s),
        "n_evaluations": int(run.n_evaluations),
        "data_sha256": json.dumps([e.sha256 for e in lik.experiments]),
        "data_names": json.dumps([e.name for e in lik.experiments]),
        "start_json": json.dumps(run.start.tolist()),
        "priors_json": run.priors.to_json(),
        "diagnostics_json": json.dumps({
            "tau": run.diagnostics.tau.tolist(),
            "n_over_tau": run.diagnostics.n_over_tau,
            "acceptance": run.diagnostics.acceptance,
            "max_rhat": run.diagnostics.max_rhat,
            "min_ess": run.diagnostics.min_ess,
            "converged": run.diagnostics.converged,
            "problems": list(run.diagnostics.problems),
        }),
    }
    layout = getattr(lik, "layout", None)
    if layout is not None:
        attrs["record_layout_json"] = json.dumps(layout.to_dict())
        scales = getattr(lik, "record_scales", None)
        if scales is not None:  # the parameter row each record's noise level was sized at
            attrs["record_scale_at_json"] = json.dumps(
                {"at": scales.at.tolist(), "reference_m": scales.reference_m})
    if run.lsq is not None:
        # (with estimated initial states they follow, as in the mechanical names)
        x0 = getattr(run.lsq, "x0", None)
        theta = run.lsq.theta if x0 is None else np.r_[run.lsq.theta, np.ravel(x0)]
        attrs["lsq_theta_json"] = json.dumps(theta.tolist())
        attrs["lsq_fit_percent_json"] = json.dumps(run.lsq.fit_percent.tolist())
    return attrs


def _chunks(n: int, size: int):
    for i in range(0, n, size):
        yield slice(i, min(i + size, n))


def _pointwise_group(lik, draws: np.ndarray, obs: dict, attrs: dict):
    """The ``log_likelihood`` group: pointwise terms of every draw, float32.

    ``draws`` has shape (chain, draw, P); ``obs`` are the observation coordinates.
    """
    import xarray as xr

    n_chain, n_draw, n_par = draws.shape
    flat = draws.reshape(-1, n_par)
    n_obs = sum(e.n_samples for e in lik.experiments)
    n_out = lik.experiments[0].n_outputs
    ll = np.empty((flat.shape[0], n_obs, n_out))
    for sl in _chunks(flat.shape[0], 64):
        ll[sl] = np.concatenate(lik.pointwise(flat[sl]), axis=1)
    cd = {"chain": np.arange(n_chain), "draw": np.arange(n_draw)}
    return xr.Dataset(
        {"y": (("chain", "draw", "obs", "output"),
               ll.reshape(n_chain, n_draw, n_obs, n_out).astype(np.float32))},
        coords={**cd, **obs}, attrs=attrs,
    )


def to_inference_data(run, *, n_predictive: int = 100, pointwise: bool = True, rng=None):
    """Assemble an ``arviz.InferenceData`` from a :class:`~.sampling.PosteriorRun`.

    Parameters
    ----------
    run : PosteriorRun
    n_predictive : int
        Largest number of draws (over all chains) for the posterior predictive group
        (:func:`predictive_subset`); 0 leaves the group out.
    pointwise : bool
        Compute the ``log_likelihood`` group (one simulation per retained draw).  With
        False the group is left out (it is most of the file: draws x observations x
        outputs float32 terms); :func:`with_pointwise_loglik` rebuilds it exactly.
    rng : numpy.random.Generator or int, optional
        For the noise draws of the posterior predictive.

    Returns
    -------
    arviz.InferenceData
    """
    import xarray as xr

    az = arviz()
    rng = np.random.default_rng(rng)
    lik = run.likelihood
    exps = lik.experiments
    draws = run.draws  # (chain, draw, P)
    n_chain, n_draw, n_par = draws.shape
    cd = {"chain": np.arange(n_chain), "draw": np.arange(n_draw)}
    attrs = _attrs(run)

    variables = {nm: (("chain", "draw"), draws[:, :, i]) for i, nm in enumerate(run.names)}
    if lik.layout is not None:
        # several records: the model parameters at the population centre (e.g. g_v =
        # mu_g_v), so that code written for one record (modal propagation) finds them
        mech = lik.split(draws.reshape(-1, n_par))[0]
        for j, nm in enumerate(lik.mech_names):
            if nm not in variables:
                variables[nm] = (("chain", "draw"), mech[:, j].reshape(n_chain, n_draw))
    posterior = xr.Dataset(variables, coords=cd, attrs=attrs)
    sample_stats = xr.Dataset(
        {
            "lp": (("chain", "draw"), run.retained_log_prob),
            "total_log_likelihood": (("chain", "draw"), run.retained_log_likelihood),
        },
        coords=cd, attrs=attrs,
    )
    obs = _obs_coords(exps)
    n_out = exps[0].n_outputs
    y_obs = np.concatenate([e.y_m for e in exps])
    observed = xr.Dataset({"y": (("obs", "output"), y_obs)}, coords=obs, attrs=attrs)
    constant = xr.Dataset(
        {"v_volt": (("obs",), np.concatenate([e.v_volt for e in exps]))},
        coords={k: v for k, v in obs.items() if k != "output"}, attrs=attrs,
    )
    groups = {
        "posterior": posterior,
        "sample_stats": sample_stats,
        "observed_data": observed,
        "constant_data": constant,
    }

    if pointwise:
        groups["log_likelihood"] = _pointwise_group(lik, draws, obs, attrs)

    if n_predictive > 0:
        ch, idx = predictive_subset(n_chain, n_draw, n_predictive)
        sub = draws[np.ix_(ch, idx)].reshape(-1, n_par)
        y_hat = np.concatenate(lik.predict_theta(sub), axis=1)
        noise = np.concatenate(lik.noise_draws(sub, rng), axis=1)
        shape = (ch.size, idx.size, y_obs.shape[0], n_out)
        step_m = predictive_quantum(y_obs)
        groups["posterior_predictive"] = xr.Dataset(
            {
                "y": _packed(("chain", "draw", "obs", "output"),
                             (y_hat + noise).reshape(shape), step_m),
                "y_hat": _packed(("chain", "draw", "obs", "output"),
                                 y_hat.reshape(shape), step_m),
            },
            coords={"chain": ch, "draw": idx, **obs}, attrs=attrs,
        )
    return az.InferenceData(**groups)


def predictive_subset(n_chain: int, n_draw: int, n_predictive: int
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Chains and draws of the posterior predictive group: at most ``n_predictive`` draws.

    ``d = n_predictive // n_chain`` draws per chain (at least 1, at most ``n_draw``), evenly
    spaced, from ``ceil(n_predictive / d)`` evenly spaced chains (all chains when there
    are enough).  With 56 walkers and 20 draws that is one draw from each of 20 walkers,
    not one from each of the 56.

    Returns
    -------
    chains : ndarray of int, shape (n_c,)
    draws : ndarray of int, shape (d,)

    Examples
    --------
    >>> ch, dr = predictive_subset(56, 18, 20)
    >>> ch.size * dr.size
    20
    >>> [a.size for a in predictive_subset(24, 8, 48)]
    [24, 2]
    """
    d = int(min(n_draw, max(1, n_predictive // n_chain)))
    n_c = int(min(n_chain, -(-n_predictive // d)))
    chains = np.unique(np.linspace(0, n_chain - 1, n_c).round().astype(int))
    draws = np.unique(np.linspace(0, n_draw - 1, d).round().astype(int))
    return chains, draws


#: The predictive values are stored as 32-bit integers in steps of this fraction of the
#: smallest standard deviation of an observed output (rounded down to a power of ten):
#: 1e-4 x std.  For the ECP 210 records that is 1e-7 m, 1/44 of an encoder count, and
#: the rounding error (at most half a step) moves a band quantile by at most that much.
PREDICTIVE_RELATIVE_STEP = 1e-4


def predictive_quantum(y_obs: np.ndarray) -> float:
    """Storage step of the posterior predictive values, m (see
    :data:`PREDICTIVE_RELATIVE_STEP`); 0 when the observed outputs do not vary."""
    sd = np.std(np.asarray(y_obs, dtype=float), axis=0)
    sd = sd[np.isfinite(sd) & (sd > 0)]
    if sd.size == 0:
        return 0.0
    return float(10.0 ** np.floor(np.log10(PREDICTIVE_RELATIVE_STEP * sd.min())))


def _packed(dims, values: np.ndarray, step: float):
    """A float32 DataArray that NetCDF stores as int32 multiples of ``step`` (CF packing:
    ``scale_factor``), or plain float32 when a value would not fit or ``step`` is 0.

    Packed integers of a smooth signal have mostly constant high bytes, which the byte
    shuffle and zlib of :func:`save_idata` remove; float32 mantissas are noise to zlib."""
    import xarray as xr

    arr = xr.DataArray(values.astype(np.float32), dims=dims)
    lim = np.iinfo(np.int32).max - 1
    if step > 0 and np.all(np.isfinite(values)) and np.abs(values).max() / step < lim:
        arr.encoding = {"dtype": "int32", "scale_factor": step,
                        "_FillValue": np.iinfo(np.int32).min}
    return arr


def posterior_matrix(idata, names=None) -> np.ndarray:
    """Posterior draws as an array of shape (chain, draw, P) in ``names`` order.

    ``names`` defaults to the ``parameter_names`` attribute written by
    :func:`to_inference_data`.
    """
    post = idata.posterior
    if names is None:
        names = json.loads(post.attrs["parameter_names"])
    return np.stack([post[nm].values for nm in names], axis=-1)


def extension_from_idata(idata):
    """The model extension of a run (an ``Extension``), or None for the linear model."""
    name = idata.posterior.attrs.get("extension", "")
    if not name:
        return None

    return get_extension(str(name))


def model_from_idata(idata):
    """The ``LinearModel`` a run was made with (from the posterior attributes).

    For a run with a model extension this is its linear (free-damping) part, whose
    parameters come first in the run's parameter vector.
    """

    a = idata.posterior.attrs
    if "rig_toml" in a:  # a rig other than the chain
        return LinearModel(rig_from_toml(a["rig_toml"], where="idata"), a["damping"])
    return LinearModel(Rig(tuple(json.loads(a["springs_n_m"]))), a["damping"])


def _rig_toml(rig) -> str:
    return rig_to_toml(rig)


def priors_from_idata(idata):
    """The ``PriorSet`` of a run."""

    return PriorSet.from_json(idata.posterior.attrs["priors_json"])


def experiments_from_idata(idata) -> list:
    """The experiments a run was fitted to, rebuilt from observed and constant data."""

    obs = idata.observed_data
    y = obs["y"].values
    v = idata.constant_data["v_volt"].values
    names = obs["experiment"].values.astype(str)
    t = obs["t_s"].values
    shas = json.loads(idata.posterior.attrs.get("data_sha256", "[]"))
    out = []
    order = list(dict.fromkeys(names.tolist()))
    for i, nm in enumerate(order):
        sel = names == nm
        out.append(Experiment(t[sel], v[sel], y[sel], name=nm,
                              sha256=shas[i] if i < len(shas) else ""))
    return out


def likelihood_from_idata(idata, experiments=None):
    """A ``Likelihood`` with the run's model, extension and noise, on its own or other
    experiments."""

    exps = experiments_from_idata(idata) if experiments is None else experiments
    a = idata.posterior.attrs
    layout = a.get("record_layout_json")
    if layout:
        at = a.get("record_scale_at_json")
        return Likelihood(model_from_idata(idata), tuple(exps), a["noise"],
                          extension_from_idata(idata),
                          RecordLayout.from_dict(json.loads(layout)),
                          scale_at=None if at is None else RecordScales.reference(
                              **json.loads(at)))
    return Likelihood(model_from_idata(idata), tuple(exps), a["noise"],
                      extension_from_idata(idata),
                      initial_state=a.get("initial_state", "rest"))


def with_pointwise_loglik(idata):
    """InferenceData with its ``log_likelihood`` group, rebuilt if it was left out.

    The terms are recomputed from the posterior draws (stored in float64) and the observed
    data with the run's model, extension and noise (:func:`likelihood_from_idata`), by the
    same code as :func:`to_inference_data`, so they equal the terms a run with
    ``pointwise=True`` stores, bit for bit.

    Parameters
    ----------
    idata : arviz.InferenceData
        A run's InferenceData (from :func:`to_inference_data` or :func:`load_idata`).

    Returns
    -------
    arviz.InferenceData
        ``idata`` itself when it has the group, else a copy with the group added.
    """
    if "log_likelihood" in idata.groups():
        return idata
    lik = likelihood_from_idata(idata)
    group = _pointwise_group(lik, posterior_matrix(idata), _obs_coords(lik.experiments),
                             dict(idata.posterior.attrs))
    out = idata.copy()
    out.add_groups({"log_likelihood": group})
    return out


#: NetCDF compression of every numeric variable: zlib level 4 after the HDF5 byte
#: shuffle (on the float32 pointwise log-likelihood it gives about 25 % less than zlib
#: alone; levels above 4 gain under 1 %).  Lossless.
NETCDF_COMPRESSION = {"zlib": True, "complevel": 4, "shuffle": True}


def save_idata(idata, path: str | os.PathLike) -> Path:
    """Write InferenceData to compressed NetCDF atomically (temporary file, then rename).

    Every numeric and string variable is compressed losslessly
    (:data:`NETCDF_COMPRESSION`; strings as character arrays); the dtypes are those of
    ``idata`` (``log_likelihood`` is float32 from :func:`to_inference_data`, the
    ``posterior_predictive`` values are packed in steps of :func:`predictive_quantum` by
    their encoding; the posterior draws stay float64).

    Returns
    -------
    pathlib.Path
        The path written.
    """
    import errno
    import shutil

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    # HDF5 does not fail cleanly when the disk fills up during a write (errors from
    # destructors, even a segmentation fault): check the free space first
    need = int(1.1 * sum(idata[g].nbytes for g in idata.groups())) + 1024 * 1024
    free = shutil.disk_usage(path.parent).free
    if free < need:
        raise OSError(errno.ENOSPC, f"cannot write {path}: {os.strerror(errno.ENOSPC)} (needs "
                      f"about {need} bytes, {free} are free)")
    # ArviZ's own ``compress`` sets zlib only; with it off, xarray takes each variable's
    # ``encoding``, set here on shallow copies so the caller's object is not changed
    groups = {}
    for g in idata.groups():
        ds = idata[g].copy(deep=False)
        for var in ds.variables.values():
            if np.issubdtype(var.dtype, np.number) and var.ndim > 0:
                var.encoding = {**var.encoding, **NETCDF_COMPRESSION}
            elif var.dtype.kind in "OUS" and var.ndim > 0:
                # strings (the ``experiment`` label of every observation) as compressed
                # character arrays: variable-length strings cannot be compressed (1.4 MB
                # per group for the four records of the main job)
                var.encoding = {**var.encoding, "dtype": "S1", **NETCDF_COMPRESSION}
        groups[g] = ds
    out = arviz().InferenceData(attrs=dict(getattr(idata, "attrs", {}) or {}), **groups)
    out.to_netcdf(str(tmp), compress=False)
    os.replace(tmp, path)
    return path


def load_idata(path: str | os.PathLike):
    """Read InferenceData from NetCDF fully into memory (no file handle stays open)."""
    az = arviz()
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such InferenceData file")
    with az.rc_context({"data.load": "eager"}):
        return az.from_netcdf(str(path))
