"""Every parameter of a public function is documented (docs/conventions.md).

A public function is one listed in ``__all__`` of a public module of the package (no
component of its dotted name starts with ``_``), wherever it is defined.  Its numpydoc
``Parameters`` (or ``Other Parameters``) section must name each parameter of its
signature, and name nothing else.  ``x, y : float`` documents both names; ``*args`` and
``**kwargs`` are written with or without their stars.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import warnings

import pytest

import bayesmodal

docscrape = pytest.importorskip("numpydoc.docscrape",
                                reason="numpydoc (the test and docs extras) parses docstrings")


def public_modules() -> list[str]:
    names = [m.name for m in pkgutil.walk_packages(bayesmodal.__path__, "bayesmodal.")
             if not any(p.startswith("_") for p in m.name.split(".")[1:])]
    return ["bayesmodal", *names]


def public_functions() -> dict[str, object]:
    """``module.qualname`` of the defining module -> function, each function once."""
    out: dict[str, object] = {}
    for name in public_modules():
        module = importlib.import_module(name)
        for attr in getattr(module, "__all__", ()):
            obj = getattr(module, attr, None)
            if inspect.isfunction(obj):
                out.setdefault(f"{obj.__module__}.{obj.__qualname__}", obj)
    return out


def documented(func) -> set[str]:
    """Names in the Parameters and Other Parameters sections of ``func``'s docstring."""
    with warnings.catch_warnings():
        # numpydoc warns about sections it does not know; that is not this test's business
        warnings.simplefilter("ignore")
        doc = docscrape.NumpyDocString(inspect.getdoc(func) or "")
    names = set()
    for p in [*doc["Parameters"], *doc["Other Parameters"]]:
        names |= {n.strip().lstrip("*") for n in p.name.split(",") if n.strip()}
    return names


def undocumented(func) -> tuple[str, ...]:
    """Parameters of ``func``'s signature its docstring does not document, in order."""
    have = documented(func)
    return tuple(p for p in inspect.signature(func).parameters if p not in have)


def stale(func) -> set[str]:
    """Documented names that are not parameters of ``func``."""
    return documented(func) - set(inspect.signature(func).parameters)

# Public functions whose docstrings leave parameters out today (91 functions,
# 211 parameters, of 315 public functions), by the defining module without the
# leading "bayesmodal.".  The list may only shrink: document the parameters and delete the
# entry (the test below fails on an entry that is no longer needed).  Issue #37.
UNDOCUMENTED: dict[str, tuple[str, ...]] = {
    "_errors.one_line": ('exc',),
    "_versions.dependency_versions": ('names',),
    "bench.time_per_call": ('fn', 'min_time_s', 'repeat', 'clock'),
    "data.file_sha256": ('path',),
    "data.find_data": ('name',),
    "data.in_data_root": ('name', 'root'),
    "data.save_csv": ('experiment', 'path'),
    "discrepancy.checks._stats.ljung_box": ('x', 'lags', 'n_fitted'),
    "discrepancy.checks.drive_gain.input_events": ('u', 'min_samples'),
    "discrepancy.checks.friction.force_residual": ('res', 'window'),
    "discrepancy.checks.input_correlation.lag_phrase": ('lag_s', 'resolution_s'),
    "discrepancy.checks.input_correlation.prediction_lag": ('y', 'y_pred', 'dt', 'max_lag'),
    "discrepancy.checks.residuals.noise_level": ('residual', 'quantum_m'),
    "discrepancy.checks.residuals.smooth_derivative": ('polyorder',),
    "discrepancy.checks.spectrum.model_frequencies_hz": ('res',),
    "discrepancy.diagnosis.forward.forward_select": ('first_fit',),
    "discrepancy.diagnosis.null.diagnostic_statistics": ('diags',),
    "discrepancy.diagnosis.null.infer_quantum": ('experiments', 'default', 'tol'),
    "discrepancy.diagnosis.null.quantise": ('y', 'quantum_m'),
    "plots.diagnosis.plot_before_after": ('diagnosis', 'experiment', 'ax'),
    "plots.diagnosis.write_plots": ('diagnosis', 'experiments', 'folder'),
    "discrepancy.diagnosis.scoring.criterion_for": ('experiments',),
    "discrepancy.diagnosis.scoring.held_out_significant": ('held_out', 'level'),
    "discrepancy.diagnosis.scoring.laplace_sd": ('ext', 'rig', 'theta', 'experiments'),
    "discrepancy.diagnosis.scoring.profiled_nll": ('residuals',),
    "discrepancy.diagnosis.starts.best_start": ('ext', 'rig', 'theta_lin', 'experiments'),
    "discrepancy.diagnosis.starts.best_starts": (
        'ext', 'rig', 'theta_lin', 'experiments', 'n', 'weights'),
    "discrepancy.diagnosis.starts.extra_starts": ('ext', 'rig', 'theta_lin', 'experiments'),
    "fit.effects.extension_fit_at": (
        'experiments', 'ext', 'rig', 'theta', 'linear', 'weights'),
    "model.kernels._codegen.padded_width": ('nb',),
    "ema.analyze.default_band": ('frf', 'n_modes'),
    "ema.frf.band_coherence": ('frf', 'band'),
    "ema.excitation.is_pulse_train": ('u', 'max_duty'),
    "ema.excitation.is_step_input": ('u', 'max_changes'),
    "ema.irf.frequency_grid": ('n_samples', 'dt'),
    "ema.peaks.mode_indicator": ('frf', 'reliable'),
    "inference.evidence.bayes_factor": ('evidences', 'a', 'b'),
    "inference.loo.information_criteria": ('idata',),
    "inference.evidence.kass_raftery": ('two_ln_b',),
    "inference.crossval.run_fold": ('spec', 'experiments', 'heldout', 'progress'),
    "inference.idata.experiments_from_idata": ('idata',),
    "inference.idata.extension_from_idata": ('idata',),
    "inference.idata.likelihood_from_idata": ('idata', 'experiments'),
    "inference.idata.load_idata": ('path',),
    "inference.idata.model_from_idata": ('idata',),
    "inference.idata.posterior_matrix": ('idata', 'names'),
    "inference.idata.priors_from_idata": ('idata',),
    "inference.idata.save_idata": ('idata', 'path'),
    "inference.mode.z_bounds": ('priors',),
    "inference.noise.arp.pacf_to_ar": ('kappa',),
    "inference.noise.base.check_residual": ('r', 'n_outputs'),
    "inference.noise.kalman.kalman_pointwise": (
        'model', 'theta_mech', 'q', 'sigma', 'v', 'y', 'dt', 'v0'),
    "inference.predictive.score_samples": ('name', 'y', 'y_pred', 'loglik'),
    "inference.propagate.credible_interval": ('axis',),
    "inference.propagate.hdi": ('samples', 'prob', 'axis'),
    "inference.propagate.modal_intervals": ('ms', 'prob'),
    "inference.noise_choice.choose_noise": ('max_p',),
    "inference.record_layout.parse_layout": ('text', 'noise_per_record', 'noise_scale'),
    "inference.sampling.default_thin": ('n_walkers', 'n_kept_steps', 'target'),
    "inference.summary.comparison_markdown": ('rows',),
    "inference.summary.parameter_intervals": ('idata', 'prob'),
    "inference.summary.posterior_modes": ('idata', 'methods'),
    "inference.summary.summary_dict": ('idata', 'prob', 'modal'),
    "runs.outputs.write_run": ('idata', 'out_dir', 'prob', 'plots'),
    "inference.threads.resolve_threads": ('threads',),
    "runs.batch.run_one": ('config', 'out_dir', 'resume', 'force'),
    "runs.checkpoint.checkpoint_iteration": ('path', 'name'),
    "runs.checkpoint.last_state": ('path',),
    "runs.checkpoint.read_trace": ('path',),
    "runs.checkpoint.trace_stride": ('n_steps', 'burn', 'thin', 'max_steps'),
    "runs.compare.write_comparison": ('comparison', 'out_dir', 'plots'),
    "runs.crossval.write_crossval": ('result', 'out_dir', 'plots', 'calibration'),
    "runs.provenance.data_digests": ('paths',),
    "runs.report.write_report": ('run_dir', 'state'),
    "runs.rerun.json_differences": ('a', 'b', 'path', 'limit'),
    "runs.rerun.recorded_config": ('run_dir',),
    "runs.prepare.default_out_dir": ('config', 'out_root'),
    "runs.prepare.prepare_run": ('config',),
    "runs.verdict.cell_statuses": ('record', 'prob'),
    "runs.verdict.coverage_status": (
        'coverage', 'prob', 'coverage_pit', 'band_factor_pit', 'level'),
    "runs.verdict.record_status": ('record', 'n_records', 'prob'),
    "static.static_levels": ('rig', 'g_v'),
    "static.steady_state": ('plateau_options',),
}


def failures(functions) -> dict[str, tuple[str, ...]]:
    out = {}
    for key, func in functions.items():
        missing = undocumented(func)
        if missing:
            out[key.removeprefix("bayesmodal.")] = missing
    return out


def test_public_function_parameters_are_documented():
    found = failures(public_functions())
    new = {k: v for k, v in found.items() if not set(v) <= set(UNDOCUMENTED.get(k, ()))}
    assert new == {}, ("document these parameters in the numpydoc Parameters section: "
                       f"{new}")


def test_allow_list_only_shrinks():
    found = failures(public_functions())
    fixed = {k: tuple(p for p in v if p not in found.get(k, ())) for k, v in UNDOCUMENTED.items()}
    fixed = {k: v for k, v in fixed.items() if v}
    assert fixed == {}, f"documented now: remove them from UNDOCUMENTED: {fixed}"


def test_no_stale_parameter_names():
    stale_names = {k: sorted(stale(f)) for k, f in public_functions().items() if stale(f)}
    assert stale_names == {}, f"documented names that are not parameters: {stale_names}"


def test_the_walk_finds_the_public_functions():
    functions = public_functions()
    assert "bayesmodal.inference.sampling.sample_posterior" in functions
    assert "bayesmodal.fit.lsq.fit_lsq" in functions
    assert not any(k.split(".")[-1].startswith("_") for k in functions)
    assert len(functions) > 250


def _ok(x, y, *, rng=None):
    """A function documented in full.

    Parameters
    ----------
    x, y : float
        Two numbers, m.
    rng : numpy.random.Generator or int, optional
        Random numbers.
    """


def _missing(x, dt, **kwargs):
    """A function that forgets ``dt``.

    Parameters
    ----------
    x : ndarray, shape (n,), m
    **kwargs
        Passed on.
    """


def _stale(x):
    """Documents a parameter it no longer has.

    Parameters
    ----------
    x : float
    y : float
    """


def test_checker_on_known_docstrings():
    # negative controls: the forgotten and the stale parameter are found
    assert undocumented(_ok) == () and stale(_ok) == set()
    assert undocumented(_missing) == ("dt",)
    assert stale(_stale) == {"y"}
    assert failures({"m._missing": _missing, "m._ok": _ok}) == {"m._missing": ("dt",)}
