"""Progress display: plain lines (no escape codes) unless the stream is a terminal."""

from __future__ import annotations

import io

import numpy as np
import pytest
from test_inference_sampling import _synthetic

from bayesmodal._progress import progress_bar
from bayesmodal.inference import sample_posterior


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_plain_lines_every_tenth_when_not_a_terminal():
    out = io.StringIO()
    with progress_bar(200, desc="work", unit="item", file=out) as bar:
        for _ in range(200):
            bar.update()
    lines = out.getvalue().splitlines()
    assert len(lines) == 10  # 10 %, 20 %, ..., 100 %
    assert lines[0].startswith("work: 20/200 items (10 %)")
    assert lines[-1].startswith("work: 200/200 items (100 %)")
    assert "\r" not in out.getvalue() and "\x1b" not in out.getvalue()


def test_terminal_gets_a_tqdm_bar_negative_control():
    out = _Tty()
    with progress_bar(50, desc="work", file=out) as bar:
        for _ in range(50):
            bar.update()
    assert "\r" in out.getvalue()  # what the plain mode avoids


def test_disabled_writes_nothing():
    out = io.StringIO()
    with progress_bar(50, desc="work", enabled=False, file=out) as bar:
        bar.update(50)
    assert out.getvalue() == ""


def test_sampler_progress_is_plain_in_a_log_and_changes_no_draw(capsys):
    model, exp = _synthetic(n=300, seed=1)
    kw = dict(noise="ar1", n_walkers=24, n_steps=20, burn=5, rng=3, warn=False)
    quiet = sample_posterior(exp, model, progress=False, **kw)
    assert capsys.readouterr().err == ""
    shown = sample_posterior(exp, model, progress=True, **kw)
    err = capsys.readouterr().err
    assert "sampling: 20/20 steps (100 %)" in err
    assert "\r" not in err and "\x1b" not in err
    assert np.array_equal(quiet.chain, shown.chain)
    assert np.array_equal(quiet.log_prob, shown.log_prob)


@pytest.mark.parametrize("restart", [None, 4])
def test_draws_equal_emcee_run_mcmc(restart, monkeypatch):
    """The progress loop iterates exactly what ``EnsembleSampler.run_mcmc`` would."""
    from bayesmodal.inference import ensemble

    model, exp = _synthetic(n=300, seed=2)
    kw = dict(noise="ar1", n_walkers=24, n_steps=16, burn=8, rng=5, warn=False,
              restart=restart)
    ours = sample_posterior(exp, model, **kw)

    def run_mcmc(sampler, state, n, progress):
        sampler.run_mcmc(state if state is not None else sampler.get_last_sample(), n)

    monkeypatch.setattr(ensemble, "_advance", run_mcmc)
    ref = sample_posterior(exp, model, **kw)
    assert np.array_equal(ours.chain, ref.chain)
