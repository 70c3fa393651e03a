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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from .._errors import DataError, ModelError
from ._kernels import (
    aligned_empty,
    direct_kernel,
    direct_steps_kernel,
    modal_affine_sums_kernel,
    modal_feed_kernel,
    modal_kernel,
    modal_steps_kernel,
    modal_sums_kernel,
    padded_width,
)
from ._qep import modal_form_mck
from ._resid_kernels import ar1_sums_lanes

__all__ = [
    "Discretized",
    "LinearSimulator",
    "discretize_zoh",
    "simulate_linear",
    "simulate_state_space",
]

#: Largest relative mismatch of the modal static gain accepted for the modal kernel.
_MODAL_DC_RTOL = 1e-10


@dataclass(frozen=True)
class Discretized:
    """Zero-order-hold discretisation of a batch of continuous systems.

    Attributes
    ----------
    Ad : ndarray, shape (nb, s, s)
    Bd : ndarray, shape (nb, s)
    dt : float
        Sample interval, s.
    """

    Ad: np.ndarray
    Bd: np.ndarray
    dt: float


def _check_dt(dt: float) -> float:
    if not (np.isscalar(dt) and np.isfinite(dt) and dt > 0):
        raise DataError(f"sample interval dt must be finite and > 0 s, got {dt!r}")
    return float(dt)


def step_groups(steps: np.ndarray, t_max: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The distinct values of a record's steps and, for each step, which one it is.

    Steps are differences of stamps, each exact only to the stamps' own rounding, so two
    steps are the same when they differ by less than ``4 eps max(|t|)`` (a difference of
    two floats near ``t`` is off by up to ``eps |t|``; stamps rounded to ms that should give
    exactly 1 ms give 0.001 +- 1e-18..1e-15 s).

    Parameters
    ----------
    steps : ndarray, shape (N - 1,)
        Steps ``t[k+1] - t[k]``, s (> 0).
    t_max : float
        Largest ``|t|`` of the stamps, s (the resolution's scale; default the sum of
        the steps).

    Returns
    -------
    values : ndarray, shape (J,)
        Each group's first step, s, in order of first appearance.
    index : ndarray of int64, shape (N,)
        ``values[index[k]]`` is the step from sample ``k`` to ``k + 1``; the last entry
        (no step follows) is 0.

    Examples
    --------
    >>> v, i = step_groups(np.diff(np.array([0.0, 0.001, 0.002, 0.004, 0.005])))
    >>> v.tolist(), i.tolist()
    ([0.001, 0.002], [0, 0, 1, 0, 0])
    """
    h = np.asarray(steps, dtype=float)
    scale = max(float(t_max), float(np.sum(h)))
    tol = 4 * np.finfo(float).eps * scale
    order = np.argsort(h, kind="stable")
    hs = h[order]
    label_sorted = np.concatenate([[0], np.cumsum(np.diff(hs) > tol)])
    label = np.empty(h.size, np.int64)
    label[order] = label_sorted
    # renumber the groups by first appearance, so that step 0's group is block 0
    _, first = np.unique(label, return_index=True)
    rank = np.empty(first.size, np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    index = rank[label]
    # each group's first step stands for it (all agree to the stamps' resolution; a
    # constant array of steps gives back its value exactly)
    values = h[np.sort(first)]
    return values, np.concatenate([index, [0]])


def _check_steps(dt, n_samples: int):
    """``(dt, None, None)`` for a scalar step, else ``(h_0, values, index)`` of
    :func:`step_groups` for per-sample steps (one group: a uniform step again)."""
    if np.isscalar(dt):
        return _check_dt(dt), None, None
    h = np.asarray(dt, dtype=float)
    if h.shape != (n_samples - 1,):
        raise DataError(f"steps must be a scalar dt or have shape ({n_samples - 1},) (one "
                        f"per interval between the {n_samples} samples), got {h.shape}")
    if not np.all(np.isfinite(h) & (h > 0)):
        k = int(np.argmax(~(np.isfinite(h) & (h > 0))))
        raise DataError(f"steps must be finite and > 0 s; step {k} is {h[k]!r}")
    values, index = step_groups(h)
    if values.size == 1:
        return float(values[0]), None, None
    return float(values[0]), values, index


def _step_ratios(mu0: np.ndarray, mus: list[np.ndarray]) -> np.ndarray:
    """Input weights ``r_j = (mu_j - 1) / (mu_0 - 1)``, shape (J, nb, m); ``r_0 = 1``
    exactly."""
    r = np.empty((len(mus),) + mu0.shape, complex)
    r[0] = 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        for j in range(1, len(mus)):
            r[j] = (mus[j] - 1.0) / (mu0 - 1.0)
    return r


def discretize_zoh(A: np.ndarray, B: np.ndarray, dt: float) -> Discretized:
    """Exact ZOH discretisation of ``x' = A x + B u`` for a stack of systems.

    Parameters
    ----------
    A : ndarray, shape (nb, s, s) or (s, s)
    B : ndarray, shape (nb, s) or (s,)
    dt : float
        Sample interval, s (> 0).

    Returns
    -------
    Discretized
        With leading batch dimension (nb = 1 for unbatched input).

    Examples
    --------
    >>> d = discretize_zoh(np.array([[-1.0]]), np.array([1.0]), 0.1)
    >>> float(d.Ad[0, 0, 0])  # exp(-0.1)
    0.9048374180359595
    """
    dt = _check_dt(dt)
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.ndim == 2:
        A = A[None]
    if B.ndim == 1:
        B = B[None]
    nb, s, _ = A.shape
    F = np.zeros((nb, s + 1, s + 1))
    F[:, :s, :s] = A * dt
    F[:, :s, s] = B * dt
    E = expm(F)
    return Discretized(Ad=E[:, :s, :s], Bd=E[:, :s, s], dt=dt)


def _modal_form(A, B, x0, dt, n_out):
    """Scaled modal form of each lane, or None for lanes where it is not reliable.

    Returns ``ok`` (nb,) and, for all lanes, ``mu`` (nb, m), ``G`` (nb, n_out, m),
    ``w0`` (nb, m) (meaningful only where ``ok``).
    """
    nb, s, _ = A.shape
    if s % 2:
        return np.zeros(nb, bool), None, None, None
    n_modes = s // 2
    lam, V = np.linalg.eig(A)
    # modes with positive imaginary part, in a fixed order
    order = np.argsort(-lam.imag, axis=1, kind="stable")[:, :n_modes]
    lam_m = np.take_along_axis(lam, order, axis=1)
    scale = np.abs(lam).max(axis=1, keepdims=True) + 1e-300
    ok = np.all(lam_m.imag > 1e-8 * scale, axis=1)
    rhs = np.concatenate([B[..., None], x0[..., None]], axis=2).astype(complex)
    try:
        sol = np.linalg.solve(V, rhs)
    except np.linalg.LinAlgError:
        return np.zeros(nb, bool), None, None, None
    beta = np.take_along_axis(sol[..., 0], order, axis=1)
    z0 = np.take_along_axis(sol[..., 1], order, axis=1)
    mu = np.exp(lam_m * dt)
    with np.errstate(divide="ignore", invalid="ignore"):
        gamma = beta * (mu - 1.0) / lam_m
        ok &= np.all(np.abs(gamma) > 1e-12 * np.abs(gamma).max(axis=1, keepdims=True), axis=1)
        Vm = np.take_along_axis(V[:, :n_out, :], order[:, None, :], axis=2)
        G = 2.0 * Vm * gamma[:, None, :]
        w0 = z0 / gamma
        # static gain of the modal recursion vs the exact -A^-1 B (positions)
        dc_modal = np.real(np.sum(G / (1.0 - mu)[:, None, :], axis=2))
    try:
        dc_exact = -np.linalg.solve(A, B[..., None])[:, :n_out, 0]
    except np.linalg.LinAlgError:
        return np.zeros(nb, bool), None, None, None
    err = np.max(np.abs(dc_modal - dc_exact), axis=1)
    ok &= np.isfinite(err) & (err <= _MODAL_DC_RTOL * (np.abs(dc_exact).max(axis=1) + 1e-300))
    ok &= np.all(np.isfinite(G), axis=(1, 2)) & np.all(np.isfinite(w0), axis=1)
    return ok, mu, G, w0


class LinearSimulator:
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

    def _dispatch(self, ok, mu, G, w0, A, B, x0b, lanes_last: bool = False,
                  sums_against: np.ndarray | None = None, affine: np.ndarray | None = None,
                  steps: tuple | None = None, feed: np.ndarray | None = None,
                  **second_order) -> np.ndarray:
        """Run each chunk of lanes with the modal kernel if all its lanes allow, else direct
        (with ``sums_against``: return the residual sums, see :meth:`residual_sums`)."""
        nb, s = x0b.shape
        width = padded_width(nb)
        n_chunks = -(-nb // width)
        sums = None
        if sums_against is not None:
            sums = np.zeros((n_chunks, 4 * self.n_out, width))
            Y = None
        else:
            Y = self._buffer(n_chunks, width)
        direct = None
        nm = s // 2
        for c in range(n_chunks):
            lanes = np.arange(c * width, (c + 1) * width)
            real = np.where(lanes < nb, lanes, nb - 1)  # pad with a repeated valid lane
            # per-lane gain and offset; padding lanes get g = v0 = 0 (their sums are dropped)
            gv = (None if affine is None
                  else np.where(lanes < nb, affine[:, np.minimum(lanes, nb - 1)], 0.0))
            if steps is not None:
                A, B = self._run_steps(c, real, ok, steps, G, w0, A, B, x0b, second_order,
                                       Y, width, feed)
                continue
            if np.all(ok[real]):
                # blocks on 64 bytes: off it the kernel took 17-18.5 instead of 11.6 us
                # per evaluation (_kernels.ALIGN_BYTES)
                Q = aligned_empty((2 * nm + 2 * nm * self.n_out, width))
                Q[0 : 2 * nm : 2] = mu[real].real.T
                Q[1 : 2 * nm : 2] = mu[real].imag.T
                g = G[real].reshape(width, self.n_out * nm).T  # rows i*nm + m
                Q[2 * nm :: 2] = g.real
                Q[2 * nm + 1 :: 2] = g.imag
                W = aligned_empty((2 * nm, width))
                W[0::2] = w0[real].real.T
                W[1::2] = w0[real].imag.T
                if sums is not None and affine is not None:
                    modal_affine_sums_kernel(nm, self.n_out, width)(
                        Q.ravel(), self.u, W.ravel(), W.ravel().copy(), gv.ravel(),
                        sums_against.ravel(), sums[c].reshape(-1))
                    continue
                if sums is not None:
                    modal_sums_kernel(nm, self.n_out, width)(
                        Q.ravel(), self.u, W.ravel(), sums_against.ravel(), sums[c].reshape(-1))
                    continue
                if feed is not None:  # acceleration outputs: the input's feedthrough
                    D = aligned_empty((self.n_out, width))
                    D[:] = feed[real].T
                    modal_feed_kernel(nm, self.n_out, width)(Q.ravel(), self.u, W.ravel(),
                                                             D.ravel(), Y[c].reshape(-1))
                    continue
                modal_kernel(nm, self.n_out, width)(Q.ravel(), self.u, W.ravel(),
                                                    Y[c].reshape(-1))
            elif self.outputs is not None:
                if A is None:
                    A, B = _second_order_state_space(**second_order)
                if direct is None:
                    direct = discretize_zoh(A, B, self.dt)
                P = aligned_empty((s * s + s, width))
                P[: s * s] = direct.Ad[real].reshape(width, s * s).T
                P[s * s :] = direct.Bd[real].T
                X = np.ascontiguousarray(x0b[real].T)
                Xs = np.empty((self.u.size, s, width))
                direct_kernel(s, s, width)(P.ravel(), self.u, X.ravel(), Xs.reshape(-1))
                _outputs_of_states(self.outputs, Xs, self.u, A[real], B[real], Y[c])
            else:
                if direct is None:
                    if A is None:
                        A, B = _second_order_state_space(**second_order)
                    direct = discretize_zoh(A, B, self.dt)
                P = aligned_empty((s * s + s, width))
                P[: s * s] = direct.Ad[real].reshape(width, s * s).T
                P[s * s :] = direct.Bd[real].T
                X = np.ascontiguousarray(x0b[real].T)
                Yc = Y[c] if sums is None else np.empty((self.u.size, self.n_out, width))
                direct_kernel(s, self.n_out, width)(P.ravel(), self.u, X.ravel(),
                                                    Yc.reshape(-1))
                if sums is not None:
                    extra = ()
                    if affine is not None:
                        Bc = np.empty_like(Yc)
                        X = np.ascontiguousarray(x0b[real].T)  # the kernel advanced X
                        direct_kernel(s, self.n_out, width)(P.ravel(), np.ones(self.u.size),
                                                            X.ravel(), Bc.reshape(-1))
                        extra = (Bc[None], gv[0], gv[1])
                    for i, a in enumerate(ar1_sums_lanes(sums_against, Yc[None], width,
                                                         *extra)):
                        sums[c, i * self.n_out : (i + 1) * self.n_out] = a
        if sums is not None:
            # (chunk, 4 n_out, width) -> four (n_out, nb) arrays
            flat = sums.reshape(n_chunks, 4, self.n_out, width).transpose(1, 2, 0, 3)
            flat = flat.reshape(4, self.n_out, n_chunks * width)[:, :, :nb]
            return tuple(np.ascontiguousarray(a) for a in flat)
        if lanes_last:
            return Y
        # (chunk, N, out, lane) -> (lane, N, out); a view when there is one chunk
        y = Y.transpose(0, 3, 1, 2)
        if n_chunks == 1:
            return y[0, :nb]
        return y.reshape(n_chunks * width, self.u.size, self.n_out)[:nb]

    def _run_steps(self, c, real, ok, steps, G, w0, A, B, x0b, second_order, Y, width,
                   feed=None):
        """Chunk ``c`` (lanes ``real``) over the recorded steps: the modal recursion with a
        pole and an input weight per distinct step when all its lanes allow, else the
        full-state recursion with the exact ZOH of each distinct step."""
        s = x0b.shape[1]
        nm = s // 2
        n_steps = self.step_values.size
        idx = self.step_index
        mu, r = steps
        if mu is not None and np.all(ok[real]):
            g_rows = 2 * nm * self.n_out
            Q = aligned_empty((g_rows + 4 * nm * n_steps, width))
            g = G[real].reshape(width, self.n_out * nm).T  # rows i*nm + m
            Q[0:g_rows:2] = g.real
            Q[1:g_rows:2] = g.imag
            for j in range(n_steps):
                o = g_rows + 4 * nm * j
                Q[o : o + 2 * nm : 2] = mu[j, real].real.T
                Q[o + 1 : o + 2 * nm : 2] = mu[j, real].imag.T
                Q[o + 2 * nm : o + 4 * nm : 2] = r[j, real].real.T
                Q[o + 2 * nm + 1 : o + 4 * nm : 2] = r[j, real].imag.T
            W = aligned_empty((2 * nm, width))
            W[0::2] = w0[real].real.T
            W[1::2] = w0[real].imag.T
            modal_steps_kernel(nm, self.n_out, width)(Q.ravel(), idx, self.u, W.ravel(),
                                                      Y[c].reshape(-1))
            if feed is not None:
                _add_feedthrough(Y[c], self.u, feed[real])
            return A, B
        if A is None:
            A, B = _second_order_state_space(**second_order)
        rows = s * s + s
        P = aligned_empty((n_steps * rows, width))
        for j, h in enumerate(self.step_values):
            d = discretize_zoh(A[real], B[real], float(h))
            P[j * rows : j * rows + s * s] = d.Ad.reshape(width, s * s).T
            P[j * rows + s * s : (j + 1) * rows] = d.Bd.T
        X = np.ascontiguousarray(x0b[real].T)
        if self.outputs is None:
            direct_steps_kernel(s, self.n_out, width)(P.ravel(), idx, self.u, X.ravel(),
                                                      Y[c].reshape(-1))
            return A, B
        Xs = np.empty((self.u.size, s, width))
        direct_steps_kernel(s, s, width)(P.ravel(), idx, self.u, X.ravel(), Xs.reshape(-1))
        _outputs_of_states(self.outputs, Xs, self.u, A[real], B[real], Y[c])
        return A, B


def _output_form(spec, ok, mu, G, masses, C, K, b, dt):
    """Output gains and feedthrough of the outputs ``spec`` (n_out, 2) from the modal
    form of all positions: ``ok`` (nb,), ``G_out`` (nb, n_out, m), ``feed`` (nb, n_out)
    (None without acceleration outputs).

    ``lambda = log(mu) / dt`` is exact while ``|Im lambda| dt < pi``, which the bound of
    :func:`_steps_from_poles` guarantees; lanes outside it are left to the full-state
    recursion.
    """
    dofs, orders = spec[:, 0], spec[:, 1]
    G_out = G[:, dofs, :]
    if np.any(orders > 0):
        inv_m = 1.0 / masses[:, :, None]
        bound = (np.sqrt(np.sum((inv_m * C) ** 2, axis=(1, 2)))
                 + np.sqrt(np.sqrt(np.sum((inv_m * K) ** 2, axis=(1, 2)))))
        ok = ok & np.isfinite(bound) & (bound * dt < np.pi)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            lam = np.log(mu) / dt  # (lanes without a modal form hold zeros: not used)
            G_out = G_out * lam[:, None, :] ** orders[None, :, None]
        ok = ok & np.all(np.isfinite(G_out), axis=(1, 2))
    feed = None
    if np.any(orders == 2):
        feed = np.where(orders == 2, (b / masses)[:, dofs], 0.0)
    return ok, G_out, feed


def _add_feedthrough(Yc, u, feed_lanes):
    """``Yc[k, i, :] += feed[:, i] u[k]`` in place (acceleration outputs)."""
    Yc += u[:, None, None] * feed_lanes.T[None]


def _outputs_of_states(spec, Xs, u, A, B, Yc):
    """Outputs ``spec`` of full states ``Xs`` (N, s, width) into ``Yc`` (N, n_out, width):
    positions and velocities are states, accelerations the velocity rows of
    ``A x + B u`` at each sample."""
    n = Xs.shape[1] // 2
    for i, (dof, order) in enumerate(spec):
        if order < 2:
            Yc[:, i, :] = Xs[:, dof + n * order, :]
        else:
            row = n + dof
            Yc[:, i, :] = (np.einsum("wj,kjw->kw", A[:, row, :], Xs)
                           + u[:, None] * B[None, :, row])


def _steps_from_poles(mu0, values, masses, C, K):
    """``(mu, r)`` of each distinct step from the first step's poles, or None.

    ``mu_j = exp(lambda h_j) = exp(log(mu_0) h_j / h_0)``: the principal logarithm gives
    back ``lambda h_0`` when ``|Im(lambda)| h_0 < pi``, which holds for every mode when
    ``(||M^-1 C|| + sqrt(||M^-1 K||)) h_0 < pi`` (a root of ``lambda^2 M + lambda C + K``
    has ``|lambda|^2 <= |lambda| ||M^-1 C|| + ||M^-1 K||``; Frobenius norms bound the
    spectral ones).  This saves a modal decomposition per step.
    """
    h0 = float(values[0])
    inv_m = 1.0 / masses[:, :, None]
    bound = (np.sqrt(np.sum((inv_m * C) ** 2, axis=(1, 2)))
             + np.sqrt(np.sqrt(np.sum((inv_m * K) ** 2, axis=(1, 2)))))
    if not np.all(np.isfinite(bound) & (bound * h0 < np.pi)):
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        log_mu0 = np.log(mu0)
        mus = [mu0] + [np.exp(log_mu0 * (float(h) / h0)) for h in values[1:]]
    return np.stack(mus), _step_ratios(mu0, mus)


def _steps_form(forms):
    """Combine the modal forms of each distinct step: ``ok`` (nb,) and ``(mu, r)``, each
    shape (J, nb, m), poles and input weights (``_step_ratios``).

    ``forms`` is ``[(ok_j, mu_j, G_j), ...]``, step 0 first.  Each step's output gains
    are ``G_j = r_j G_0`` when the modes come in the same order; a lane where they do
    not (to 1e-8, far above the rounding of ``r_j``) is left to the full-state recursion.
    """
    ok0, mu0, G0 = forms[0]
    if mu0 is None or any(f[1] is None for f in forms):
        nb = ok0.size
        return np.zeros(nb, bool), (None, None)
    ok = ok0.copy()
    r = _step_ratios(mu0, [f[1] for f in forms])
    with np.errstate(invalid="ignore", over="ignore"):
        for j, (ok_j, _, G_j) in enumerate(forms[1:], start=1):
            err = np.max(np.abs(G_j - r[j][:, None, :] * G0), axis=(1, 2))
            size = np.max(np.abs(G_j), axis=(1, 2))
            ok &= ok_j & (err <= 1e-8 * size) & np.all(np.isfinite(r[j]), axis=1)
    return ok, (np.stack([f[1] for f in forms]), r)


def _second_order_state_space(masses, C, K, b):
    nb, n = masses.shape
    inv_m = 1.0 / masses
    A = np.zeros((nb, 2 * n, 2 * n))
    A[:, :n, n:] = np.eye(n)
    A[:, n:, :n] = -inv_m[:, :, None] * K
    A[:, n:, n:] = -inv_m[:, :, None] * C
    B = np.zeros((nb, 2 * n))
    B[:, n:] = inv_m * b
    return A, B


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
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.ndim == 2:
        A = A[None]
    if B.ndim == 1:
        B = B[None]
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

