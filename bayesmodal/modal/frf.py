"""Frequency response functions of the rig model (report section 4).

For state ``z = (x, x')`` the transfer function from voltage to positions is (eq. 42)

    H_v(j omega) = C_out (j omega I - A)^-1 B,   C_out = [I 0].

Writing ``Z = (j omega I - A)^-1 B V`` in its two blocks gives ``X' = j omega X`` and
``j omega X' = -M^-1 K X - M^-1 C X' + M^-1 b V``, i.e.

    H_v(j omega) = (K - omega^2 M + j omega C)^-1 b,

which is what is evaluated: an n x n solve instead of a 2n x 2n one, with the same result.
The force-to-position function divides by the voltage-to-force gain (eq. 43),
``H_f = H_v / g_v = (K - omega^2 M + j omega C)^-1 e_1``.
"""

from __future__ import annotations

import numpy as np

from .._errors import ModelError

__all__ = ["transfer_function"]

#: Memory budget of one batched solve, bytes.
_CHUNK_BYTES = 32 * 2**20


def transfer_function(model, theta, omega_rad_s, *, input: str = "voltage") -> np.ndarray:
    """Frequency response of the cart positions to the motor voltage or force.

    Parameters
    ----------
    model : LinearModel
        Rig model.
    theta : array_like, shape (..., n_params)
        Parameters in ``model.names`` order; leading dimensions are a batch.
    omega_rad_s : array_like, shape (n_freq,)
        Angular frequencies, rad/s (>= 0).
    input : {"voltage", "force"}
        ``"voltage"``: X/V in m/V (eq. 42); ``"force"``: X/F in m/N (eq. 43).

    Returns
    -------
    ndarray, shape (..., n_freq, n_carts), complex
        ``H[..., k, i]`` is the response of cart ``i + 1`` at ``omega_rad_s[k]``.

    Examples
    --------
    >>> import numpy as np
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> model = LinearModel(Rig(), "proportional")
    >>> H = transfer_function(model, [6.223, 1.565, 1.461, 1.146, 1.528, 8.583e-05], [0.0])
    >>> np.round(H.real * 1e3, 4)  # static gain K^-1 b, mm/V (report eq. 13)
    array([[31.8365, 23.7965, 15.7146]])
    """
    if input not in ("voltage", "force"):
        raise ModelError(f"input must be 'voltage' or 'force', got {input!r}")
    theta = model.check(theta)
    w = np.asarray(omega_rad_s, dtype=float)
    if w.ndim != 1 or not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ModelError("omega_rad_s must be a 1-D array of finite frequencies >= 0 rad/s")
    M, C, K, b = model.matrices(theta)
    if input == "force":
        b = b / b[..., :1]
    batch, n = M.shape[:-2], M.shape[-1]
    flat = [X.reshape((-1,) + X.shape[len(batch):]) for X in (M, C, K, b)]
    n_sys = flat[0].shape[0]
    out = np.empty((n_sys, w.size, n), dtype=complex)
    per_sys = max(w.size * n * n * 16 * 3, 1)
    step = max(1, _CHUNK_BYTES // per_sys)
    jw = 1j * w[:, None, None]
    for lo in range(0, n_sys, step):
        Mc, Cc, Kc, bc = (X[lo : lo + step] for X in flat)
        Z = Kc[:, None] - (w**2)[:, None, None] * Mc[:, None] + jw * Cc[:, None]
        rhs = np.broadcast_to(bc[:, None, :, None], Z.shape[:-1] + (1,)).astype(complex)
        out[lo : lo + step] = np.linalg.solve(Z, rhs)[..., 0]
    return out.reshape(batch + (w.size, n))
