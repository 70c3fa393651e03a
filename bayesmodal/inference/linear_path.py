"""The likelihood's compiled path for the linear model with white or AR(1) noise.

A sampler evaluates the likelihood thousands of times on the same records.  For the
linear model (no extension, records from rest) the residual sums of
``_resid_kernels.ar1_sums`` are accumulated inside the simulator's recursion, so the
prediction is never stored; one modal form serves every record whose simulated parameter
rows are equal; and each thread keeps its simulators, whose buffers are reused between
calls (:class:`SimulatorCache`).  :func:`linear_record_loglik` gives the numbers of the
straightforward computation (simulate, residual, sums) bit for bit
(``tests/test_likelihood_buffers.py``).
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING

import numpy as np

from ..model.simulate import LinearSimulator
from ..model.system import LinearModel
from .noise_terms import level_column, loglik_from_sums

if TYPE_CHECKING:  # the likelihood's type only: it builds on this module
    from .likelihood import Likelihood

__all__ = ["SimulatorCache", "prepare_linear", "fast_path", "linear_record_loglik"]


class SimulatorCache:
    """Simulators (``LinearSimulator``) kept between likelihood calls, one per thread and key.

    A simulator reuses its output buffer, so a sampler's thousands of calls do not
    allocate and page in a fresh (N, n_out, nb) array each time; the buffer is
    overwritten by the next call, hence one set per thread.  Pickling drops the buffers
    (a process pool rebuilds them on first use).
    """

    def __init__(self) -> None:
        self._by_thread: dict = {}

    def get(self, key, u: np.ndarray, dt: float, n_out: int) -> LinearSimulator:
        sims = self._by_thread.setdefault(threading.get_ident(), {})
        sim = sims.get(key)
        if sim is None:
            sim = sims[key] = LinearSimulator(u, dt, n_out)
        return sim

    def __getstate__(self) -> dict:
        return {}

    def __setstate__(self, state: dict) -> None:
        self._by_thread = {}


def prepare_linear(model: LinearModel, theta: np.ndarray, sim: LinearSimulator) -> tuple:
    """The modal form of admissible linear-model parameter rows for ``sim.run_prepared``
    (what ``simulate_linear`` computes before its recursion).

    Parameters
    ----------
    model : LinearModel
    theta : ndarray, shape (nb, n_params)
        Admissible parameter rows in ``model.names`` order.
    sim : LinearSimulator
        The simulator of the record (its input and sample interval).

    Returns
    -------
    tuple
        The prepared modal form, as ``LinearSimulator.prepare_second_order`` gives it.
    """
    M, C, K, b = model.matrices(theta)
    return sim.prepare_second_order(np.diagonal(M, axis1=1, axis2=2), C, K, b)


def fast_path(model: LinearModel) -> bool:
    """Whether the likelihood can read the simulator's buffer directly.

    Parameters
    ----------
    model : LinearModel

    Returns
    -------
    bool
        True when the model's outputs are the simulator's leading states (chain rigs).
    """
    return getattr(model, "output_index", None) is None


def linear_record_loglik(lik: Likelihood, th: np.ndarray) -> np.ndarray:
    """White or AR(1) log-likelihood per record of the linear model from rest.

    The numbers of ``Likelihood._basic_loglik`` bit for bit, faster: one modal form per
    sample interval serves every record whose simulated parameter rows are equal (with
    an input offset, the unit-gain rows, equal across records whenever only ``g_v`` and
    ``v0`` are per record), and the residual sums of ``g (a + v0 b)`` (or of the plain
    simulation when no offset is sampled) are accumulated inside the recursion, which
    runs the unit-gain responses ``a = S1(v)`` and ``b = S1(1)`` side by side without
    storing either (``LinearSimulator.residual_sums``).

    Parameters
    ----------
    lik : Likelihood
        With no extension, records from rest, white or AR(1) noise and a chain rig
        (:func:`fast_path`).
    th : ndarray, shape (nb, P)
        Admissible parameter rows.

    Returns
    -------
    ndarray, shape (nb, n_records)
        Not yet cleaned of non-finite values.
    """
    nb = th.shape[0]
    n_mech = lik.n_mech
    out = np.empty((nb, lik.n_records))
    prep = {}  # sample interval -> (parameter rows, their modal form)
    for r, e in enumerate(lik.experiments):
        full, v0 = lik.record_theta(th, r)
        mech = full[:, :n_mech]
        affine = bool(np.any(v0))  # as _basic_loglik: the gain inside when v0 = 0
        sim_rows = mech
        if affine:
            sim_rows = mech.copy()
            sim_rows[:, 0] = 1.0
        sim = lik._sims.get(r, e.v_volt, e.dt, lik.model.n_carts)
        rows, form = prep.get(e.dt, (None, None))
        if form is None or not np.array_equal(sim_rows, rows):
            form = prepare_linear(lik.model, sim_rows, sim)
            prep[e.dt] = (sim_rows, form)
        sums = (sim.residual_sums(form, e.y_m, mech[:, 0], v0) if affine
                else sim.residual_sums(form, e.y_m))
        sigma, phi = lik.sigma_phi(full[:, n_mech:])
        out[:, r] = loglik_from_sums(*sums, e.n_samples,
                                     sigma * level_column(lik._scale_rows(th, r)), phi)
    return out
