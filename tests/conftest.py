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
from bayesmodal.model.system import LinearModel, Rig  # noqa: E402


def pytest_configure(config):
    """Give each pytest-xdist worker its share of the cores for BLAS.

    Every worker is a process with OpenBLAS's own thread pool, one thread per core by
    default: with a worker per core, a least-squares SVD's threads wait for each other on
    an oversubscribed machine (a 7 200 x 12 SVD 3 ms on one thread, 16 ms on two beside
    another busy process; ``bayesmodal._blas``, ``benchmarks/blas_threads.py``).
    """
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0") or 0)
    if workers > 0:
        from bayesmodal._blas import blas_share, limit_blas

        limit_blas(blas_share(workers))


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


# ----------------------------------------------------------------------------- tolerances
# A tolerance comes from the computation's own error (docs/testing.md, "Tolerances"):
# these helpers give first-order bounds for the shared numerical kernels.

#: Unit roundoff of float64 (2.2e-16).
EPS = np.finfo(float).eps


def solve_tol(A) -> float:
    """Relative error bound of a backward-stable solve ``A x = b``: ``cond(A) n eps``.

    ``A`` may be a stack, shape (..., n, n); the bound of the worst member is returned.
    """
    A = np.asarray(A)
    return float(np.max(np.linalg.cond(A))) * A.shape[-1] * EPS


def eig_rtol(M, K, lam, *, backward=None) -> np.ndarray:
    """Relative error bound of eigenvalues ``lam`` of the definite pencil ``K u = lam M u``.

    A method with relative backward error ``b`` (default ``n eps``, a backward-stable
    solver such as ``eigh``) returns the exact eigenvalues of ``(K + E, M + F)``,
    ``||E|| <= b ||K||``, ``||F|| <= b ||M||``; to first order each eigenvalue then moves by
    at most ``b (||K|| + lam ||M||) ||M^-1||`` (2-norms), returned relative to ``lam``.
    The bound on ``omega = sqrt(lam)`` is half of it, so it serves for both.
    """
    M = np.asarray(M, float)
    K = np.asarray(K, float)
    lam = np.asarray(lam, float)
    b = M.shape[-1] * EPS if backward is None else backward
    norm_m = np.linalg.norm(M, 2, axis=(-2, -1))[..., None]
    norm_k = np.linalg.norm(K, 2, axis=(-2, -1))[..., None]
    norm_minv = 1.0 / np.linalg.eigvalsh(M).min(axis=-1)[..., None]
    return b * (norm_k + lam * norm_m) * norm_minv / lam


def eig_angle_tol(M, K, lam, *, backward=None) -> np.ndarray:
    """Bound on the sine of the M-angle between computed and exact mode shapes.

    The eigenvalue perturbation of :func:`eig_rtol` (absolute) divided by the gap from
    each ``lam`` to its nearest neighbour (Davis-Kahan); ``inf`` gap for a single mode.
    """
    lam = np.asarray(lam, float)
    shift = eig_rtol(M, K, lam, backward=backward) * lam
    dist = np.abs(lam[..., :, None] - lam[..., None, :])
    dist = np.where(np.eye(lam.shape[-1], dtype=bool), np.inf, dist)
    return shift / np.min(dist, axis=-1)


def angle_tol(M, K, lam, *, backward=None) -> np.ndarray:
    """Bound on the sine of the plain (Euclidean) angle between computed and exact shapes:
    :func:`eig_angle_tol` scaled by ``sqrt(cond(M))`` (M-angle to plain angle), plus the
    rounding ``n eps`` of the shape's own entries."""
    M = np.asarray(M, float)
    s = eig_angle_tol(M, K, lam, backward=backward) * np.sqrt(np.linalg.cond(M))[..., None]
    return s + M.shape[-1] * EPS


def mac_tol(M, K, lam, *, backward=None) -> np.ndarray:
    """Bound on ``1 - MAC`` between computed and exact shapes: the squared sine of
    :func:`angle_tol` plus the rounding of the MAC itself, ``n eps``."""
    return angle_tol(M, K, lam, backward=backward) ** 2 + np.shape(M)[-1] * EPS


def nonsym_eig_atol(A) -> tuple[np.ndarray, np.ndarray]:
    """Absolute error bound of each eigenvalue of a general matrix ``A``, shape (..., n, n).

    A backward-stable eigensolver perturbs A by ``n eps ||A||``; eigenvalue ``i`` moves by
    that times its condition number ``1 / |y_i^H x_i|`` (unit left and right vectors).
    Returns the eigenvalues (``scipy.linalg.eig`` order) and their bounds, shape (..., n)
    each.  Use through :func:`match_eigs`.
    """
    import scipy.linalg

    A = np.asarray(A, float)
    flat = A.reshape(-1, *A.shape[-2:])
    out = []
    for a in flat:
        w, vl, vr = scipy.linalg.eig(a, left=True, right=True)
        kappa = 1.0 / np.abs(np.sum(vl.conj() * vr, axis=0))
        out.append((w, a.shape[-1] * EPS * np.linalg.norm(a, 2) * kappa))
    w = np.array([o[0] for o in out]).reshape(A.shape[:-1])
    tol = np.array([o[1] for o in out]).reshape(A.shape[:-1])
    return w, tol


def match_eigs(A, lam) -> np.ndarray:
    """The error bound of :func:`nonsym_eig_atol` for each eigenvalue in ``lam`` (shape
    (..., k)), taken from the nearest eigenvalue of A."""
    w, tol = nonsym_eig_atol(A)
    lam = np.asarray(lam)
    idx = np.argmin(np.abs(lam[..., :, None] - w[..., None, :]), axis=-1)
    return np.take_along_axis(tol, idx, axis=-1)


def zoh_rtol(A, dt, *, phase=True, n_steps=None) -> float:
    """Bound on the error of an exact zero-order-hold simulation of ``x' = A x + B u``,
    relative to the largest response, for ``A`` of shape (..., s, s) (worst member).

    Both kernels (modal coordinates, or ``expm`` and the state recursion as in ``lsim``)
    work in the eigenbasis up to rounding: each step adds ``s eps cond(V)`` relative, which
    the stable recursion accumulates over ``sum_k rho^k = 1 / (1 - rho)`` steps
    (``rho = max |exp(lambda dt)|``); an error ``dl`` of an eigenvalue (its condition
    number times ``s eps ||A||``, :func:`nonsym_eig_atol`) turns the phase by ``k dt dl``
    after k steps, at most ``dt dl / (1 - rho)`` of the response once weighted by the decay
    ``rho^k``.  ``phase=False`` leaves that term out, for identities between runs with the
    same discretisation (superposition, time invariance), which a consistent eigenvalue
    error does not break.  ``n_steps`` (the record length) caps the memory at the number
    of steps, which keeps the bound finite for an undamped system.
    """
    A = np.asarray(A, float).reshape(-1, *np.shape(A)[-2:])
    s = A.shape[-1]
    lam, dl = nonsym_eig_atol(A)
    _, V = np.linalg.eig(A)
    rho = np.max(np.abs(np.exp(lam * dt)), axis=-1)
    with np.errstate(divide="ignore"):
        memory = 1.0 / (1.0 - np.minimum(rho, 1.0))
    if n_steps is not None:
        memory = np.minimum(memory, n_steps)
    rounding = s * EPS * np.linalg.cond(V) * (1.0 + memory)
    drift = dt * np.max(dl, axis=-1) * memory if phase else 0.0
    return float(np.max(rounding + drift))


def ode_atol(n_steps, rtol, atol, scale, cond_v=1.0) -> float:
    """Global error bound of an adaptive integrator run at ``rtol``, ``atol`` over
    ``n_steps`` accepted steps on a stable system: each step's local error is held below
    ``rtol |y| + atol`` (``scale`` = max |y|); a stable system does not amplify them beyond
    the conditioning ``cond_v`` of its eigenbasis, so at most they add up."""
    return float(cond_v * n_steps * (rtol * scale + atol))


def modal_backward(method, K):
    """Relative backward error of a modal method (function or name) at its default
    settings, read from its signature: ``eigh`` is backward stable (``None``, i.e. n eps
    in :func:`eig_rtol`); ``rayleigh_modes`` guarantees a backward error below
    ``1000 tol``; matrix iteration works on ``D = K^-1 M``, formed with a solve
    (:func:`solve_tol`), and stops when the shape changes by less than ``tol``."""
    import inspect

    from bayesmodal.modal import matrix_iteration, rayleigh_modes

    name = getattr(method, "__name__", str(method))
    if "rayleigh" in name:
        return 1000 * inspect.signature(rayleigh_modes).parameters["tol"].default
    if "iteration" in name:
        return solve_tol(K) + inspect.signature(matrix_iteration).parameters["tol"].default
    return None


def shape_atol(method, M, K, omega2, U):
    """Bound on the entries of shapes normalised on cart 1 (columns of U, shape (..., n, n))
    from ``method`` against exact or ``eigh`` shapes, both errors together: a shape turned
    by an angle with sine s moves perpendicularly by s ||u|| and, after renormalising
    u_1 = 1, by at most s ||u|| (1 + max|u|).  Broadcast to the shape of U."""
    s = angle_tol(M, K, omega2, backward=modal_backward(method, K)) + angle_tol(M, K, omega2)
    norm = np.linalg.norm(U, axis=-2)
    return np.broadcast_to((s * norm * (1 + np.max(np.abs(U), axis=-2)))[..., None, :],
                           np.shape(U))


# ----------------------------------------------------------------------------- the CLI
def run_cli(argv: list[str]) -> tuple[int, str, list[str]]:
    """Run ``bayesmodal ARGV`` in this process: exit code, stdout, and stderr's lines
    (every warning shown, as the command line shows each one once)."""
    import contextlib
    import io
    import warnings

    from bayesmodal.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
            warnings.catch_warnings():
        warnings.simplefilter("always")  # shown by the CLI, one line each
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue().splitlines()


# ----------------------------------------------------------------------------- scheduling
#: Test files that take longest in the default suite from an empty kernel cache (the ten
#: slowest tests that `scripts/test.sh` lists, summed by file), longest first.  With
#: `--dist loadfile` pytest-xdist hands files to the workers in collection order, so a
#: long file collected late finishes alone after the other worker has run out of files;
#: collected first, the short files fill in around it (longest processing time first).
LONGEST_FIRST = ("test_diagnose_hidden.py", "test_extensions.py", "test_diagnose_forward.py",
                 "test_runs_run.py", "test_docs.py", "test_inference_extension.py",
                 "test_end_stop.py", "test_effects_global_fit.py", "test_bench.py",
                 "test_diagnostics.py", "test_effects_combined_filters.py")


def pytest_collection_modifyitems(session, config, items):
    """Run the longest test files first (``LONGEST_FIRST``), the rest in their order."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    order = {id(item): i for i, item in enumerate(items)}
    items.sort(key=lambda it: (rank.get(it.path.name, len(rank)), order[id(it)]))
