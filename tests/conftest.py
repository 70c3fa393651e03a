"""Shared fixtures: measured data are read from ../shared/data or $BAYESMODAL_DATA."""

from __future__ import annotations

import os

import matplotlib
import numpy as np
import pytest
from hypothesis import settings

matplotlib.use("Agg")

# Property-test profiles (docs/testing.md): "ci" is the default, fixed-seed and modest;
# "nightly" explores far more examples.  Select with HYPOTHESIS_PROFILE=nightly or
# pytest --hypothesis-profile nightly.
settings.register_profile("ci", derandomize=True, max_examples=30, deadline=None,
                          database=None, print_blob=True)
settings.register_profile("nightly", max_examples=1000, deadline=None, database=None,
                          print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

from bayesmodal.data import data_root, find_data, load_experiment  # noqa: E402
from bayesmodal.system import LinearModel, Rig  # noqa: E402

#: Report Table 3 (free damping), in LinearModel("free").names order.
TABLE3 = np.array([6.223, 1.565, 1.461, 1.146, 2.923, 1.806, 2.002, 0.00221, 0.00001])


def measured(name: str):
    """Load a measured ECP file or skip the test with the reason."""
    p = find_data(f"ecp210-3dof/{name}")
    if p is None:
        root = data_root()
        where = os.environ.get("BAYESMODAL_DATA") or "../shared/data beside the repo"
        pytest.skip(f"measured data {name} not found (looked in {root or where})")
    return load_experiment(p)


@pytest.fixture(scope="session")
def impulses():
    return measured("data_impulses.mat")


@pytest.fixture(scope="session")
def steps():
    return measured("data_steps.mat")


@pytest.fixture
def free_model():
    return LinearModel(Rig(), "free")


@pytest.fixture
def prop_model():
    return LinearModel(Rig(), "proportional")
