"""Exact zero-order-hold simulation of the linear rig model, batched over parameter sets.

With the input held constant over each sample interval, ``x' = A x + B v`` is integrated
exactly by

    [Ad  Bd]  =  expm( [[A, B], [0, 0]] * dt )     (top block row, Van Loan)
    x[k+1] = Ad x[k] + Bd v[k]

which is what ``scipy.signal.lsim(..., interp=False)`` computes.  For speed the recursion
is run in modal coordinates when the system is underdamped: with ``A V = V diag(lambda)``,
``z = V^-1 x`` obeys ``z[k+1] = mu z[k] + gamma v[k]`` with ``mu = exp(lambda dt)`` and
``gamma = (mu - 1) / lambda * (V^-1 B)`` (the same exact ZOH formula, mode by mode).
Conjugate modes carry conjugate coordinates, so the positions are
``x_i = 2 Re sum_m V[i, m] z_m`` over the modes with positive imaginary part; scaling
``w_m = z_m / gamma_m`` leaves one multiply-add per input.  Lanes whose modal form is not
trustworthy (real or repeated eigenvalues, ill-conditioned eigenvectors, an uncontrollable
mode) are detected by comparing the modal static gain with ``-A^-1 B`` and fall back to
the full-state recursion.  Both kernels are compiled with numba, vectorised across the
batch (see ``_kernels``).

Recorded stamps.  A logger whose steps ``h_k = t[k+1] - t[k]`` differ still holds the
input between samples, so each step is integrated exactly by its own ``expm`` of the
step: ``mu_j = exp(lambda h_j)`` and ``gamma_j = (mu_j - 1) / lambda * beta``.  Stamps
rounded to milliseconds take a handful of distinct steps, each discretised once.  Scaling
the modal state by the first step's ``gamma_0`` keeps one output gain ``G`` for all steps,
and the input enters with the weight ``r_j = gamma_j / gamma_0 = (mu_j - 1) / (mu_0 - 1)``
(``beta`` and ``lambda`` cancel): ``w[k+1] = mu_j w[k] + r_j v[k]``, two more multiplies
per mode and step than the uniform recursion.

Velocity and acceleration outputs.  An eigenvector of ``A`` for the state ``(x, x')``
has velocity rows ``lambda`` times its position rows, so a velocity output is the modal
sum with the gains ``lambda_m G[i, m]``.  An acceleration output is the velocity rows of
``x' = A x + B u`` at the sample: ``A V = V diag(lambda)`` gives the modal sum with the
gains ``lambda_m^2 G[i, m]``, and ``B u_k`` adds the feedthrough ``(M^-1 b)_i u_k`` of
the input held from ``t_k`` (``y_k = C_out x_k + D u_k``, ``C_out`` over the full
state).  The recursion is the same; only the output gains change, plus one multiply-add
per acceleration output and sample.  ``lambda_m = log(mu_m) / dt`` is exact while every
``|Im lambda| dt < pi`` (checked by a bound, as for recorded stamps); lanes outside it
and lanes without a modal form take the full-state recursion and the output matrix.

The discretisation and a record's steps are in ``discretize``, the modal form of a batch in
``_modal_form``, and the loop over chunks of lanes that runs the compiled kernels in
``_chunks``.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError, ModelError
from ._chunks import ChunkRunner
from ._kernels import aligned_empty
from ._modal_form import (
    _MODAL_DC_RTOL,
    _modal_form,
    _output_form,
    _second_order_state_space,
    _steps_form,
    _steps_from_poles,
)
from ._qep import modal_form_mck
from .discretize import (
    Discretized,
    _batched,
    _check_steps,
    discretize_zoh,
    step_groups,  # noqa: F401  (re-exported: defined in discretize)
)

__all__ = [
    "Discretized",
    "LinearSimulator",
    "discretize_zoh",
    "simulate_linear",
    "simulate_state_space",
]


class LinearSimulator(ChunkRunner):
    """Simulate one input record for many parameter sets, reusing work buffers.

    This is the object a likelihood holds on to: each call simulates a batch (for emcee, all
    walkers) and returns a view into an internal buffer that the next call overwrites.

    Parameters
    ----------
    u : ndarray, shape (N,)
        Input samples (V), held over each sample interval.
    dt : float or ndarray, shape (N - 1,)
        Sample interval, s; or the recorded steps ``t[k+1] - t[k]`` of a record whose
        stamps jitter (each distinct step discretised once, see :func:`step_groups`).
    n_out : int
        Number of outputs: the leading states (the cart positions), or ``len(outputs)``.
    outputs : sequence of (int, int), optional
        Degree of freedom and time derivative (0 position, 1 velocity, 2 acceleration) of
        each output, for the second-order methods (:meth:`run_second_order`,
        :meth:`prepare_second_order`); default the first ``n_out`` positions.

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> model = LinearModel(Rig(), "proportional")
    >>> sim = LinearSimulator(np.ones(200), 0.005, model.n_carts)
    >>> A, B = model.state_space(np.array([[6.2, 1.5, 1.5, 1.1, 1.5, 1e-4]]))
    >>> sim.run(A, B).shape
    (1, 200, 3)
    """

    def __init__(self, u: np.ndarray, dt: float, n_out: int, outputs=None) -> None:
        u = np.ascontiguousarray(u, dtype=np.float64)
        if u.ndim != 1 or u.size < 1:
            raise DataError(f"input u must be a non-empty 1-D array, got shape {u.shape}")
        if not np.all(np.isfinite(u)):
            raise DataError("input u has non-finite values (NaN or inf)")
        self.u = u
        # with recorded steps, dt is the first step's value (the modal gains' scale)
        self.dt, self.step_values, self.step_index = _check_steps(dt, u.size)
        self._time_key = self.dt if self.step_values is None else tuple(self.step_values)
        self.n_out = int(n_out)
        self.outputs = None
        if outputs is not None:
            spec = np.array([(int(d), int(o)) for d, o in outputs], dtype=np.int64)
            spec = spec.reshape(-1, 2)
            if spec.shape[0] != self.n_out:
                raise ModelError(f"outputs lists {spec.shape[0]} outputs but n_out is "
                                 f"{self.n_out}; give one (dof, order) pair per output")
            if np.any(spec[:, 0] < 0) or np.any((spec[:, 1] < 0) | (spec[:, 1] > 2)):
                raise ModelError(f"outputs must be (dof >= 0, order 0, 1 or 2) pairs, got "
                                 f"{spec.tolist()}")
            # all positions in order: the plain path, bit for bit
            if not (np.all(spec[:, 1] == 0) and np.array_equal(spec[:, 0],
                                                               np.arange(self.n_out))):
                self.outputs = spec
        self._outputs_key = None if self.outputs is None else self.outputs.tobytes()
        self._buffers: dict[tuple[int, int], np.ndarray] = {}

    def _buffer(self, n_chunks: int, width: int) -> np.ndarray:
        key = (n_chunks, width)
        buf = self._buffers.get(key)
        if buf is None:
            buf = aligned_empty((n_chunks, self.u.size, self.n_out, width))
            self._buffers = {key: buf}  # keep one buffer: the last shape used
        return buf

    def run(self, A: np.ndarray, B: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """Simulate a stack of systems.

        Parameters
        ----------
        A : ndarray, shape (nb, s, s)
        B : ndarray, shape (nb, s)
        x0 : ndarray, shape (s,) or (nb, s), optional
            Initial state; zero by default.

        Returns
        -------
        y : ndarray, shape (nb, N, n_out)
            View into the simulator's buffer (valid until the next call);
            ``y[:, k]`` is the state at ``t = k dt``.
        """
        A = np.asarray(A, dtype=float)
        B = np.asarray(B, dtype=float)
        if A.ndim != 3 or B.ndim != 2 or A.shape[:2] != B.shape or A.shape[1] != A.shape[2]:
            raise ModelError(f"A must be (nb, s, s) and B (nb, s); got {A.shape} and {B.shape}")
        if self.outputs is not None:
            raise ModelError("outputs other than the leading states need the second-order "
                             "form; use run_second_order")
        x0b = self._initial(x0, A.shape[0], A.shape[1])
        ok, mu, G, w0 = _modal_form(A, B, x0b, self.dt, self.n_out)
        steps = None
        if self.step_values is not None:
            forms = [(ok, mu, G)] + [_modal_form(A, B, x0b, h, self.n_out)[:3]
                                     for h in self.step_values[1:]]
            ok, steps = _steps_form(forms)
        return self._dispatch(ok, mu, G, w0, A, B, x0b, steps=steps)

    def run_second_order(
        self,
        masses: np.ndarray,
        C: np.ndarray,
        K: np.ndarray,
        b: np.ndarray,
        x0: np.ndarray | None = None,
    ) -> np.ndarray:
        """Simulate ``diag(masses) x'' + C x' + K x = b u`` for a batch; outputs positions.

        Faster than ``run`` for this structure: the modal form comes from a compiled
        quadratic-eigenproblem solver (``_qep``); lanes it cannot handle (overdamped or
        nearly repeated modes) go through the general path.

        Parameters
        ----------
        masses : ndarray, shape (nb, n), kg
        C, K : ndarray, shape (nb, n, n), symmetric, N s/m and N/m
        b : ndarray, shape (nb, n), N per input unit
        x0 : ndarray, shape (2n,) or (nb, 2n), optional
            Initial positions (m) and velocities (m/s); zero by default.

        Returns
        -------
        y : ndarray, shape (nb, N, n_out)
            View into the simulator's buffer (valid until the next call).
        """
        return self.run_prepared(self.prepare_second_order(masses, C, K, b, x0))

    def prepare_second_order(self, masses, C, K, b, x0=None) -> tuple:
        """The modal form of a batch of second-order systems, for :meth:`run_prepared`.

        It depends on the parameters and ``dt``, not on the input: simulators of records
        with the same ``dt`` and ``n_out`` can share it (several records of one rig, or a
        record and a constant input).  Arguments as :meth:`run_second_order`.
        """
        masses = np.ascontiguousarray(masses, dtype=float)
        C = np.ascontiguousarray(C, dtype=float)
        K = np.ascontiguousarray(K, dtype=float)
        b = np.ascontiguousarray(b, dtype=float)
        nb, n = masses.shape
        if C.shape != (nb, n, n) or K.shape != (nb, n, n) or b.shape != (nb, n):
            raise ModelError(
                f"masses (nb, n), C and K (nb, n, n), b (nb, n) expected; got {masses.shape}, "
                f"{C.shape}, {K.shape}, {b.shape}"
            )
        spec = self.outputs
        if spec is None and self.n_out > n:
            raise ModelError(f"n_out = {self.n_out} exceeds the {n} positions")
        if spec is not None and spec[:, 0].max() >= n:
            raise ModelError(f"outputs read degree of freedom {int(spec[:, 0].max())} of a "
                             f"system with {n}")
        n_pos = n if spec is not None else self.n_out
        x0b = np.ascontiguousarray(self._initial(x0, nb, 2 * n))
        ok, mu, G, w0, A, B = self._second_order_form(masses, C, K, b, x0b, self.dt, n_pos)
        steps = None
        if self.step_values is not None:
            steps = _steps_from_poles(mu, self.step_values, masses, C, K)
            if steps is None:  # some pole may alias on the first step: each step anew
                forms = [(ok, mu, G)] + [
                    self._second_order_form(masses, C, K, b, x0b, h, n_pos)[:3]
                    for h in self.step_values[1:]]
                ok, steps = _steps_form(forms)
            else:
                ok = ok & np.all(np.isfinite(steps[1]), axis=(0, 2))
        feed = None
        if spec is not None:
            ok, G, feed = _output_form(spec, ok, mu, G, masses, C, K, b, self.dt)
        return (self._time_key, self.n_out, self._outputs_key, ok, mu, G, w0, A, B, x0b,
                {"masses": masses, "C": C, "K": K, "b": b}, steps, feed)

    def _second_order_form(self, masses, C, K, b, x0b, dt, n_pos):
        """``ok, mu, G, w0, A, B`` of a batch for step ``dt`` and the first ``n_pos``
        positions: the compiled modal form, the general one for the lanes it cannot handle
        (``A, B`` None if none)."""
        nb, n = masses.shape
        mu = np.zeros((nb, n), complex)
        G = np.zeros((nb, n_pos, n), complex)
        w0 = np.zeros((nb, n), complex)
        ok = np.zeros(nb, bool)
        modal_form_mck(masses, C, K, b, x0b, dt, n_pos, mu, G, w0, ok)
        # static-gain check of the compiled modal form against K^-1 b
        dc_exact = np.linalg.solve(K, b[..., None])[:, :n_pos, 0]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            dc_modal = np.real(np.sum(G / (1.0 - mu)[:, None, :], axis=2))
            err = np.max(np.abs(dc_modal - dc_exact), axis=1)
        ok &= np.isfinite(err) & (
            err <= _MODAL_DC_RTOL * (np.abs(dc_exact).max(axis=1) + 1e-300)
        )
        A = B = None
        if not np.all(ok):
            A, B = _second_order_state_space(masses, C, K, b)
            bad = np.flatnonzero(~ok)
            ok2, mu2, G2, w02 = _modal_form(A[bad], B[bad], x0b[bad], dt, n_pos)
            if mu2 is not None:
                good = bad[ok2]
                mu[good], G[good], w0[good] = mu2[ok2], G2[ok2], w02[ok2]
                ok[good] = True
        return ok, mu, G, w0, A, B

    def run_prepared(self, prepared: tuple, *, lanes_last: bool = False) -> np.ndarray:
        """Simulate this simulator's input with a form of :meth:`prepare_second_order`.

        Parameters
        ----------
        prepared : tuple
            From ``prepare_second_order`` of a simulator with the same ``dt`` and ``n_out``.
        lanes_last : bool
            Return the buffer itself, shape (n_chunks, N, n_out, width), lanes innermost
            and padded to the kernel width (for compiled consumers); default the
            (nb, N, n_out) view of :meth:`run_second_order`.

        Returns
        -------
        ndarray
            A view of the simulator's buffer (valid until the next call).
        """
        ok, mu, G, w0, A, B, x0b, second_order, steps, feed = self._own(prepared)
        return self._dispatch(ok, mu, G, w0, A, B, x0b, lanes_last=lanes_last, steps=steps,
                              feed=feed, **second_order)

    def _initial(self, x0, nb: int, s: int) -> np.ndarray:
        if x0 is None:
            return np.zeros((nb, s))
        x0 = np.asarray(x0, dtype=float)
        if x0.shape not in ((s,), (nb, s)):
            raise DataError(f"x0 must have shape ({s},) or ({nb}, {s}), got {x0.shape}")
        if not np.all(np.isfinite(x0)):
            raise DataError("x0 has non-finite values")
        return np.broadcast_to(x0, (nb, s))

    def residual_sums(self, prepared: tuple, y: np.ndarray, g: np.ndarray | None = None,
                      v0: np.ndarray | None = None):
        """Residual sums of the simulated outputs against a record, without storing them.

        Parameters
        ----------
        prepared : tuple
            From :meth:`prepare_second_order` (same ``dt`` and ``n_out``).
        y : ndarray, shape (N, n_out)
            Measured outputs, N the length of this simulator's input.
        g, v0 : ndarray, shape (nb,), optional
            Per-lane gain and input offset: the prediction is then ``g (a + v0 b)`` with
            ``a`` the simulated response and ``b`` the response to a constant 1 (several
            records of one rig, ``inference.records``).

        Returns
        -------
        s00, s01, r0, rl : ndarray, each shape (n_out, nb)
            Those of ``_resid_kernels.ar1_sums(y, run_prepared(prepared))`` (or
            ``ar1_sums_affine`` of the two responses), bit for bit.
        """
        ok, mu, G, w0, A, B, x0b, second_order, steps, feed = self._own(prepared)
        if self.outputs is not None:
            raise ModelError("residual sums are computed for position outputs only; "
                             "simulate velocity or acceleration outputs with run_prepared "
                             "and form the residuals")
        if steps is not None:
            raise ModelError("residual sums are computed on a uniform grid only; simulate "
                             "the recorded steps with run_prepared and form the residuals")
        y = np.ascontiguousarray(y, dtype=float)
        if y.shape != (self.u.size, self.n_out):
            raise DataError(f"y must have shape {(self.u.size, self.n_out)}, got {y.shape}")
        affine = None
        if g is not None:
            nb = x0b.shape[0]
            affine = np.zeros((2, nb))
            affine[0], affine[1] = g, v0
        return self._dispatch(ok, mu, G, w0, A, B, x0b, sums_against=y, affine=affine,
                              **second_order)

    def _own(self, prepared: tuple) -> tuple:
        """The modal form of :meth:`prepare_second_order` without its ``dt`` and ``n_out``,
        after checking that they are this simulator's."""
        key, n_out, out_key, *form = prepared
        if key != self._time_key or n_out != self.n_out or out_key != self._outputs_key:
            raise ModelError(f"prepared form is for dt={key}, n_out={n_out} and other "
                             f"outputs; this simulator has dt={self._time_key}, "
                             f"n_out={self.n_out}: prepare it here")
        return tuple(form)


def simulate_state_space(
    A: np.ndarray,
    B: np.ndarray,
    u: np.ndarray,
    dt: float,
    n_out: int,
    x0: np.ndarray | None = None,
) -> np.ndarray:
    """Simulate a stack of continuous systems under a ZOH input; outputs are the first states.

    Parameters
    ----------
    A : ndarray, shape (nb, s, s) or (s, s)
    B : ndarray, shape (nb, s) or (s,)
    u : ndarray, shape (N,)
        Input samples, held constant over each interval.
    dt : float or ndarray, shape (N - 1,)
        Sample interval, s, or the recorded steps ``t[k+1] - t[k]``, s.
    n_out : int
        Number of leading states returned as outputs.
    x0 : ndarray, shape (s,) or (nb, s), optional
        Initial state; zero by default.

    Returns
    -------
    y : ndarray, shape (nb, N, n_out)
        ``y[:, k]`` is the state at ``t = k dt``.
    """
    A, B = _batched(A, B)
    return LinearSimulator(u, dt, n_out).run(A, B, x0)


def simulate_linear(model, theta: np.ndarray, u: np.ndarray, dt: float, x0=None) -> np.ndarray:
    """Cart positions of the linear rig model for one or many parameter sets.

    Parameters
    ----------
    model : LinearModel
    theta : ndarray, shape (n_params,) or (nb, n_params)
        Parameter vectors in ``model.names`` order.
    u : ndarray, shape (N,)
        Motor voltage, V, held over each sample interval.
    dt : float or ndarray, shape (N - 1,)
        Sample interval, s, or the recorded steps ``t[k+1] - t[k]`` of a record whose
        stamps jitter (``Experiment.sim_dt``), s.
    x0 : ndarray, shape (2n,) or (nb, 2n), optional
        Initial state (positions m, velocities m/s); zero by default.

    Returns
    -------
    y : ndarray, shape (N, n_outputs) or (nb, N, n_outputs)
        What each sensor reads (``model.rig.sensors``; every cart's position for a
        chain), in SI along +x: position m, velocity m/s, acceleration m/s^2 (at the
        sample, with the input held from it: the feedthrough of the input included).

    Raises
    ------
    ModelError
        If any parameter set is impossible (see ``LinearModel.valid``).

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> model = LinearModel(Rig(), "proportional")
    >>> theta = np.array([6.2, 1.5, 1.5, 1.1, 1.5, 1e-4])
    >>> simulate_linear(model, theta, np.ones(100), 0.005).shape
    (100, 3)
    """
    theta = np.asarray(theta, dtype=float)
    single = theta.ndim == 1
    theta = model.check(np.atleast_2d(theta))
    if theta.ndim != 2:
        raise ModelError(f"theta must have shape (n_params,) or (nb, n_params), got {theta.shape}")
    M, C, K, b = model.matrices(theta)
    masses = np.diagonal(M, axis1=1, axis2=2)
    spec = getattr(model, "output_spec", None)
    if spec is not None:  # velocity or acceleration sensors: each output as it is read
        y = LinearSimulator(u, dt, len(spec), outputs=spec).run_second_order(
            masses, C, K, b, x0)
        return y[0] if single else y
    y = LinearSimulator(u, dt, model.n_carts).run_second_order(masses, C, K, b, x0)
    out = getattr(model, "output_index", None)
    if out is not None:  # sensors on some carts, or in another order (non-chain rigs)
        y = y[..., out]
    return y[0] if single else y

