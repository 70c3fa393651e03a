"""A JSON-ready modal summary of one parameter vector."""

from __future__ import annotations

import numpy as np

from .complex_modes import state_space_modes
from .damping import modal_matrices, proportional_modal_damping
from .iteration import matrix_iteration
from .rayleigh import rayleigh_modes
from .undamped import undamped_modes

__all__ = ["modal_summary", "modal_report"]


def modal_summary(model, theta) -> dict:
    """Undamped modes and state-space damping of a rig model, as plain Python types.

    Parameters
    ----------
    model : LinearModel
    theta : array_like, shape (n_params,)
        One parameter vector in ``model.names`` order.

    Returns
    -------
    dict
        ``omega_rad_s`` (list, undamped natural frequencies, rad/s), ``zeta`` (list, from
        the state-space eigenvalues), ``damped_rad_s`` (list, rad/s), ``mode_shapes`` (one
        list per mode, undamped shapes normalised on cart 1) and ``modal_mass`` (list, kg,
        for those shapes).

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> s = modal_summary(LinearModel(Rig(), "proportional"),
    ...                   [6.223, 1.565, 1.461, 1.146, 1.528, 8.583e-05])
    >>> [round(w, 3) for w in s["omega_rad_s"]]
    [8.281, 27.402, 41.826]
    """
    theta = model.check(theta)
    if theta.ndim != 1:
        raise ValueError(f"modal_summary takes one parameter vector, got shape {theta.shape}")
    M, _, K, _ = model.matrices(theta)
    um = undamped_modes(M, K)
    cm = state_space_modes(model, theta)
    return {
        "omega_rad_s": [float(v) for v in um.omega_rad_s],
        "zeta": [float(v) for v in cm.zeta],
        "damped_rad_s": [float(v) for v in cm.damped_rad_s],
        "mode_shapes": [[float(v) for v in um.shapes[:, i]] for i in range(um.n_modes)],
        "modal_mass": [float(v) for v in np.asarray(um.modal_mass)],
    }


def modal_report(model, theta) -> dict:
    """The report's classical modal analysis of one parameter vector, as plain types.

    Runs the three undamped methods (eigenproblem, Rayleigh quotient, matrix iteration),
    the modal decomposition, the state-space (complex) modes and, for proportional damping,
    the modal damping of eq. 41 (report Tables 6-9).

    Parameters
    ----------
    model : LinearModel
    theta : array_like, shape (n_params,)

    Returns
    -------
    dict
        ``parameters``; ``methods`` mapping ``eigen``, ``rayleigh``, ``iteration`` to
        ``omega_rad_s`` and ``mode_shapes`` (plus ``kind`` for the Rayleigh stationary
        points and ``n_iterations`` for matrix iteration); ``max_method_difference``
        (largest relative difference of frequencies and largest absolute difference of
        shapes between the methods); ``modal_matrices`` (``mass``, ``stiffness``,
        ``damping``, ``damping_coupling``, ``zeta_diagonal``); ``state_space`` (``zeta``,
        ``damped_rad_s``, ``omega_rad_s``); ``proportional`` (``zeta``, ``damped_rad_s``
        from eq. 41, only for proportional damping); ``static_gain_m_per_v`` (K^-1 b).
    """

    theta = model.check(theta)
    if theta.ndim != 1:
        raise ValueError(f"modal_report takes one parameter vector, got shape {theta.shape}")
    M, C, K, b = model.matrices(theta)
    results = {
        "eigen": undamped_modes(M, K),
        "rayleigh": rayleigh_modes(M, K),
        "iteration": matrix_iteration(M, K),
    }
    methods = {}
    for name, r in results.items():
        entry = {
            "omega_rad_s": r.omega_rad_s.tolist(),
            "mode_shapes": r.shapes.T.tolist(),
            "modal_mass": r.modal_mass.tolist(),
        }
        if name == "rayleigh":
            entry["kind"] = r.kind.tolist()
        if name == "iteration":
            entry["n_iterations"] = r.n_iterations.tolist()
        methods[name] = entry
    ref = results["eigen"]
    d_omega = max(float(np.max(np.abs(r.omega_rad_s / ref.omega_rad_s - 1)))
                  for r in results.values())
    d_shape = max(float(np.max(np.abs(r.shapes - ref.shapes))) for r in results.values())
    mm = modal_matrices(M, C, K, ref.shapes)
    cm = state_space_modes(model, theta)
    out = {
        "damping": model.damping,
        "parameters": model.as_dict(theta),
        "methods": methods,
        "max_method_difference": {"omega_relative": d_omega, "shape_absolute": d_shape},
        "modal_matrices": {
            "mass": mm.mass.tolist(),
            "stiffness": mm.stiffness.tolist(),
            "damping": mm.damping.tolist(),
            "damping_coupling": float(mm.coupling),
            "zeta_diagonal": mm.zeta.tolist(),
        },
        "state_space": {
            "omega_rad_s": cm.omega_rad_s.tolist(),
            "zeta": cm.zeta.tolist(),
            "damped_rad_s": cm.damped_rad_s.tolist(),
        },
        "static_gain_m_per_v": np.linalg.solve(K, b).tolist(),
    }
    if model.damping == "proportional":
        p = model.as_dict(theta)
        md = proportional_modal_damping(ref.omega_rad_s, p["ca"], p["cb"])
        out["proportional"] = {"zeta": md.zeta.tolist(), "damped_rad_s": md.damped_rad_s.tolist()}
    return out
