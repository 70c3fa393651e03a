"""The modal form of a batch of linear systems, from which the simulator's kernels run.

With ``A V = V diag(lambda)``, ``z = V^-1 x`` obeys ``z[k+1] = mu z[k] + gamma v[k]`` with
``mu = exp(lambda dt)`` and ``gamma = (mu - 1) / lambda * (V^-1 B)``; the outputs are
``2 Re sum_m G[i, m] w_m`` over the modes with positive imaginary part, ``w_m = z_m /
gamma_m``.  ``_modal_form`` builds it for each lane of a batch and flags the lanes where it
is not trustworthy (their modal static gain differs from ``-A^-1 B``); ``_steps_form`` and
``_steps_from_poles`` give the poles and input weights of each distinct step of a record,
``_output_form`` the gains of velocity and acceleration outputs.  See
``bayesmodal.model.simulate`` for the derivations.
"""

from __future__ import annotations

import numpy as np

#: Largest relative mismatch of the modal static gain accepted for the modal kernel.
_MODAL_DC_RTOL = 1e-10


def _step_ratios(mu0: np.ndarray, mus: list[np.ndarray]) -> np.ndarray:
    """Input weights ``r_j = (mu_j - 1) / (mu_0 - 1)``, shape (J, nb, m); ``r_0 = 1``
    exactly."""
    r = np.empty((len(mus),) + mu0.shape, complex)
    r[0] = 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        for j in range(1, len(mus)):
            r[j] = (mus[j] - 1.0) / (mu0 - 1.0)
    return r



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
