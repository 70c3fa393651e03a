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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ._errors import DataError, ModelError
from ._kernels import (
    aligned_empty,
    direct_kernel,
    modal_affine_sums_kernel,
    modal_kernel,
    modal_sums_kernel,
    padded_width,
)
from ._qep import modal_form_mck

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
    dt : float
        Sample interval, s.
    n_out : int
        Number of leading states returned (the cart positions).

    Examples
    --------
    >>> from bayesmodal.system import LinearModel, Rig
    >>> model = LinearModel(Rig(), "proportional")
    >>> sim = LinearSimulator(np.ones(200), 0.005, model.n_carts)
    >>> A, B = model.state_space(np.array([[6.2, 1.5, 1.5, 1.1, 1.5, 1e-4]]))
    >>> sim.run(A, B).shape
    (1, 200, 3)
    """

    def __init__(self, u: np.ndarray, dt: float, n_out: int) -> None:
        u = np.ascontiguousarray(u, dtype=np.float64)
        if u.ndim != 1 or u.size < 1:
            raise DataError(f"input u must be a non-empty 1-D array, got shape {u.shape}")
        if not np.all(np.isfinite(u)):
            raise DataError("input u has non-finite values (NaN or inf)")
        self.u = u
        self.dt = _check_dt(dt)
        self.n_out = int(n_out)
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
        x0b = self._initial(x0, A.shape[0], A.shape[1])
        ok, mu, G, w0 = _modal_form(A, B, x0b, self.dt, self.n_out)
        return self._dispatch(ok, mu, G, w0, A, B, x0b)

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
        if self.n_out > n:
            raise ModelError(f"n_out = {self.n_out} exceeds the {n} positions")
        x0b = np.ascontiguousarray(self._initial(x0, nb, 2 * n))
        mu = np.zeros((nb, n), complex)
        G = np.zeros((nb, self.n_out, n), complex)
        w0 = np.zeros((nb, n), complex)
        ok = np.zeros(nb, bool)
        modal_form_mck(masses, C, K, b, x0b, self.dt, self.n_out, mu, G, w0, ok)
        # static-gain check of the compiled modal form against K^-1 b
        dc_exact = np.linalg.solve(K, b[..., None])[:, : self.n_out, 0]
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
            ok2, mu2, G2, w02 = _modal_form(A[bad], B[bad], x0b[bad], self.dt, self.n_out)
            if mu2 is not None:
                good = bad[ok2]
                mu[good], G[good], w0[good] = mu2[ok2], G2[ok2], w02[ok2]
                ok[good] = True
        return (self.dt, self.n_out, ok, mu, G, w0, A, B, x0b,
                {"masses": masses, "C": C, "K": K, "b": b})

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
        ok, mu, G, w0, A, B, x0b, second_order = self._own(prepared)
        return self._dispatch(ok, mu, G, w0, A, B, x0b, lanes_last=lanes_last,
                              **second_order)

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
        ok, mu, G, w0, A, B, x0b, second_order = self._own(prepared)
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
        dt, n_out, *form = prepared
        if dt != self.dt or n_out != self.n_out:
            raise ModelError(f"prepared form is for dt={dt}, n_out={n_out}; this simulator "
                             f"has dt={self.dt}, n_out={self.n_out}: prepare it here")
        return tuple(form)

    def _dispatch(self, ok, mu, G, w0, A, B, x0b, lanes_last: bool = False,
                  sums_against: np.ndarray | None = None, affine: np.ndarray | None = None,
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
                modal_kernel(nm, self.n_out, width)(Q.ravel(), self.u, W.ravel(),
                                                    Y[c].reshape(-1))
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
                    from ._resid_kernels import ar1_sums_lanes

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
    dt : float
        Sample interval, s.
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
    dt : float
        Sample interval, s.
    x0 : ndarray, shape (2n,) or (nb, 2n), optional
        Initial state (positions m, velocities m/s); zero by default.

    Returns
    -------
    y : ndarray, shape (N, n_outputs) or (nb, N, n_outputs)
        Positions of the sensed carts (``model.rig.sensors``; every cart for a chain), m.

    Raises
    ------
    ModelError
        If any parameter set is impossible (see ``LinearModel.valid``).

    Examples
    --------
    >>> from bayesmodal.system import LinearModel, Rig
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
    y = LinearSimulator(u, dt, model.n_carts).run_second_order(masses, C, K, b, x0)
    out = getattr(model, "output_index", None)
    if out is not None:  # sensors on some carts, or in another order (non-chain rigs)
        y = y[..., out]
    return y[0] if single else y

