"""The root of the package is its public API: about twenty names, each importable, the
heavy layers loaded on first use only."""

import subprocess
import sys

import bayesmodal


def test_every_public_name_resolves_and_is_documented():
    names = [n for n in bayesmodal.__all__ if n != "__version__"]
    assert 15 <= len(names) <= 25
    for name in names:
        obj = getattr(bayesmodal, name)
        assert obj is not None and name in bayesmodal.__doc__, name
    assert sorted(dir(bayesmodal)) == sorted(bayesmodal.__all__)


def test_the_lazy_names_are_the_layers_own_objects():
    from bayesmodal.discrepancy.diagnosis import diagnose
    from bayesmodal.inference import sample_posterior

    assert bayesmodal.diagnose is diagnose and bayesmodal.sample_posterior is sample_posterior


def test_import_does_not_load_the_sampler_stack():
    code = ("import sys, bayesmodal; "
            "print(' '.join(m for m in ('emcee', 'arviz', 'xarray', 'matplotlib') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == ""
    # negative control: the lazy name does load it
    code = "import sys, bayesmodal; bayesmodal.sample_posterior; print('emcee' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "True"
