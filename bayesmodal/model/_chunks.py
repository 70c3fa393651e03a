"""The loop of ``LinearSimulator`` over chunks of lanes, each run by a compiled kernel.

The lanes (parameter sets) of a batch are cut into chunks of the kernels' width (padded
with a repeated lane); a chunk whose lanes all have a trustworthy modal form runs the
modal recursion, any other chunk the full-state recursion of the exact ZOH
discretisation, on the uniform grid or over a record's distinct steps.  With a record to
compare against, the kernels return the residual sums instead of the outputs.
"""

from __future__ import annotations

import numpy as np

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
from ._modal_form import _second_order_state_space
from ._resid_kernels import ar1_sums_lanes
from .discretize import discretize_zoh

__all__ = ["ChunkRunner"]


class ChunkRunner:
    """The kernel loop of :class:`~bayesmodal.model.simulate.LinearSimulator`.

    A base class holding no state: it reads the simulator's input ``u``, ``n_out``,
    ``outputs``, ``dt``, ``step_values``, ``step_index`` and its output buffer
    (``_buffer``).
    """

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
