"""Compiled modal decomposition of ``M x'' + C x' + K x = b u`` for many parameter sets.

For symmetric ``M`` (here diagonal), ``C`` and ``K`` the state-space eigenpairs are
``lambda`` and ``[phi; lambda phi]`` with ``(lambda^2 M + lambda C + K) phi = 0`` (the
quadratic eigenvalue problem, QEP).  Its symmetric linearisation gives the orthogonality
``a_k = phi_k^T (2 lambda_k M + C) phi_k`` and the modal coordinates

    z_k' = lambda_k z_k + (phi_k^T b / a_k) u,
    z_k(0) = phi_k^T ((C + lambda_k M) x(0) + M x'(0)) / a_k,
    x = sum_k phi_k z_k        (sum over all 2n eigenpairs).

Each underdamped mode is found by Newton's method on the bordered system
``[[Q(lambda), Q'(lambda) phi], [c^T, 0]] [d phi; d lambda] = -[Q(lambda) phi; c^T phi - 1]``
started from the undamped mode (symmetric Jacobi eigen-solver) with the first-order
damping correction ``lambda_0 = i omega - phi^T C phi / (2 phi^T M phi)``.  Everything runs
in one compiled loop over the batch, which is several times cheaper than LAPACK's general
eigen-solver called through NumPy for 6x6 matrices.  Lanes where Newton does not converge
to distinct underdamped modes are flagged so that the caller can use a general method.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Newton iterations allowed per mode (3-4 are needed from the undamped start).
ITMAX = 50


@njit(cache=True)
def _jacobi_eigh(S, V):  # pragma: no cover - compiled
    """Cyclic Jacobi on the symmetric matrix S (overwritten); eigenvectors into V."""
    n = S.shape[0]
    for i in range(n):
        for j in range(n):
            V[i, j] = 1.0 if i == j else 0.0
    for _sweep in range(60):
        off = 0.0
        diag = 0.0
        for i in range(n):
            diag += S[i, i] * S[i, i]
            for j in range(i + 1, n):
                off += S[i, j] * S[i, j]
        if off <= 1e-32 * diag:
            break
        for p in range(n - 1):
            for q in range(p + 1, n):
                if S[p, q] == 0.0:
                    continue
                theta = (S[q, q] - S[p, p]) / (2.0 * S[p, q])
                t = np.sign(theta) / (abs(theta) + np.sqrt(theta * theta + 1.0))
                if theta == 0.0:
                    t = 1.0
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for k in range(n):
                    skp = S[k, p]
                    skq = S[k, q]
                    S[k, p] = c * skp - s * skq
                    S[k, q] = s * skp + c * skq
                for k in range(n):
                    spk = S[p, k]
                    sqk = S[q, k]
                    S[p, k] = c * spk - s * sqk
                    S[q, k] = s * spk + c * sqk
                for k in range(n):
                    vkp = V[k, p]
                    vkq = V[k, q]
                    V[k, p] = c * vkp - s * vkq
                    V[k, q] = s * vkp + c * vkq


@njit(cache=True)
def _csolve(A, x):  # pragma: no cover - compiled
    """Solve A y = x in place (x overwritten by y), Gaussian elimination, partial pivoting.

    Returns False if A is numerically singular.
    """
    n = A.shape[0]
    for col in range(n):
        piv = col
        best = abs(A[col, col])
        for r in range(col + 1, n):
            if abs(A[r, col]) > best:
                best = abs(A[r, col])
                piv = r
        if best == 0.0:
            return False
        if piv != col:
            for k in range(n):
                tmp = A[col, k]
                A[col, k] = A[piv, k]
                A[piv, k] = tmp
            tmp = x[col]
            x[col] = x[piv]
            x[piv] = tmp
        for r in range(col + 1, n):
            f = A[r, col] / A[col, col]
            if f != 0:
                for k in range(col, n):
                    A[r, k] -= f * A[col, k]
                x[r] -= f * x[col]
    for r in range(n - 1, -1, -1):
        acc = x[r]
        for k in range(r + 1, n):
            acc -= A[r, k] * x[k]
        x[r] = acc / A[r, r]
    return True


@njit(cache=True)
def modal_form_mck(m, C, K, b, x0, dt, n_out, mu, G, w0, ok):  # pragma: no cover - compiled
    """Scaled modal form of each lane (see module docstring).

    Parameters
    ----------
    m : (nb, n) masses (diagonal of M)
    C, K : (nb, n, n) symmetric damping and stiffness
    b : (nb, n) input vector
    x0 : (nb, 2n) initial state (positions, velocities)
    dt : float
    n_out : int
    mu : (nb, n) complex out, discrete poles exp(lambda dt)
    G : (nb, n_out, n) complex out, output gains 2 phi_i gamma
    w0 : (nb, n) complex out, scaled initial modal state
    ok : (nb,) bool out
    """
    nb, n = m.shape
    S = np.empty((n, n))
    Vr = np.empty((n, n))
    Jm = np.empty((n + 1, n + 1), np.complex128)
    rhs = np.empty(n + 1, np.complex128)
    phis = np.empty((n, n), np.complex128)
    sq = np.empty(n)
    lams = np.empty(n, np.complex128)
    for lane in range(nb):
        ok[lane] = True
        for i in range(n):
            sq[i] = np.sqrt(m[lane, i])
        for i in range(n):
            for j in range(n):
                S[i, j] = K[lane, i, j] / (sq[i] * sq[j])
        _jacobi_eigh(S, Vr)
        scale = 0.0
        for j in range(n):
            scale = max(scale, abs(S[j, j]))
        for j in range(n):
            if S[j, j] <= 0.0:
                ok[lane] = False
        if not ok[lane]:
            continue
        for j in range(n):
            omega = np.sqrt(S[j, j])
            # undamped shape phi = M^-1/2 psi, mass-normalised
            ctc = 0.0
            for i in range(n):
                phis[j, i] = Vr[i, j] / sq[i]
            for i in range(n):
                for k in range(n):
                    ctc += phis[j, i].real * C[lane, i, k] * phis[j, k].real
            lam = complex(-0.5 * ctc, omega)
            # normalisation vector c = real start shape (c^T phi = c^T c)
            cc = 0.0
            for i in range(n):
                cc += phis[j, i].real * phis[j, i].real
            converged = False
            for _it in range(ITMAX):  # noqa: B007
                # residual Q(lam) phi and Jacobian
                for i in range(n):
                    for k in range(n):
                        mik = m[lane, i] if i == k else 0.0
                        Jm[i, k] = lam * lam * mik + lam * C[lane, i, k] + K[lane, i, k]
                for i in range(n):
                    r = 0j
                    dq = 0j
                    for k in range(n):
                        r += Jm[i, k] * phis[j, k]
                        mik = m[lane, i] if i == k else 0.0
                        dq += (2.0 * lam * mik + C[lane, i, k]) * phis[j, k]
                    rhs[i] = -r
                    Jm[i, n] = dq
                cphi = 0j
                for k in range(n):
                    Jm[n, k] = Vr[k, j] / sq[k]
                    cphi += Jm[n, k] * phis[j, k]
                Jm[n, n] = 0.0
                rhs[n] = -(cphi - cc)
                if not _csolve(Jm, rhs):
                    break
                for k in range(n):
                    phis[j, k] += rhs[k]
                lam += rhs[n]
                if abs(rhs[n]) <= 1e-15 * abs(lam):
                    converged = True
                    break
            if not converged or not (lam.imag > 1e-8 * abs(lam)):
                ok[lane] = False
                break
            lams[j] = lam
        if not ok[lane]:
            continue
        # distinct modes
        for j in range(n):
            for k in range(j + 1, n):
                if abs(lams[j] - lams[k]) <= 1e-8 * abs(lams[j]):
                    ok[lane] = False
        if not ok[lane]:
            continue
        for j in range(n):
            lam = lams[j]
            a = 0j
            pb = 0j
            pz = 0j
            for i in range(n):
                qi = 2.0 * lam * m[lane, i] * phis[j, i]
                cx = (lam * m[lane, i]) * x0[lane, i] + m[lane, i] * x0[lane, n + i]
                for k in range(n):
                    qi += C[lane, i, k] * phis[j, k]
                    cx += C[lane, i, k] * x0[lane, k]
                a += phis[j, i] * qi
                pb += phis[j, i] * b[lane, i]
                pz += phis[j, i] * cx
            if a == 0:
                ok[lane] = False
                break
            beta = pb / a
            mu_j = np.exp(lam * dt)
            gamma = beta * (mu_j - 1.0) / lam
            if abs(gamma) == 0.0:
                ok[lane] = False
                break
            mu[lane, j] = mu_j
            for i in range(n_out):
                G[lane, i, j] = 2.0 * phis[j, i] * gamma
            w0[lane, j] = (pz / a) / gamma
