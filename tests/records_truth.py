"""Known-truth records that disagree: several records of one rig, each with its own drive
gain and input offset, AR(1) noise and encoder quantisation (tests and benchmarks only).

The simulator is written independently of the package's: the matrices come from
``reference_sim.rig_matrices`` (assembled by hand from the equations of motion) and the
zero-order-hold recursion from ``scipy.signal.cont2discrete`` and ``scipy.signal.dlsim``
(the package uses a modal recursion compiled with numba).
"""

from __future__ import annotations

import numpy as np
from reference_sim import rig_matrices
from scipy.signal import cont2discrete, dlsim

from bayesmodal.data import Experiment

SPRINGS = (774.0, 770.0, 396.0)
#: Shared physics: masses (kg) and free dampers (N s/m), package order without g_v.
PHYSICS = (1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.3, 0.2)
MU_GV = 5.8          # N/V, population median of the drive gain
TAU_GV = 0.05        # relative spread of the gains
V0_SD = 0.01         # V, spread of the input offsets
SIGMA = 2e-5         # m, AR(1) innovation
PHI = 0.9
M_PER_COUNT = 0.0706 / 16000
DT = 0.005


def inputs(n: int = 2000) -> dict[str, np.ndarray]:
    """Four records of ``n`` samples at the rig's amplitudes: pulses (3 V), steps (0.5 V)
    and two chirps (0.2 V, 0.5-8 Hz up, and 8-0.5 Hz down)."""
    t = np.arange(n) * DT
    period = n * DT / 3
    pulses = 3.0 * ((t % period) < 0.05)
    steps = 0.5 * ((t % period) < period / 2)
    f = 0.5 + (8.0 - 0.5) * t / t[-1]
    up = 0.2 * np.sin(2 * np.pi * np.cumsum(f) * DT)
    down = 0.2 * np.sin(2 * np.pi * np.cumsum(f[::-1]) * DT)
    return {"pulses": pulses, "steps": steps, "chirp_up": up, "chirp_down": down}


def simulate(theta_lin, v, dt=DT):
    """Cart positions (N, 3), m, of the free-damping chain under a ZOH input."""
    M, C, K, b = rig_matrices(SPRINGS, theta_lin)
    n = M.shape[0]
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    B = np.r_[np.zeros(n), Minv @ b][:, None]
    Cm = np.c_[np.eye(n), np.zeros((n, n))]
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, Cm, np.zeros((n, 1))), dt, method="zoh")
    _, y, _ = dlsim((Ad, Bd, Cd, Dd, dt), v[:, None])
    return y


def measure(y, rng):
    """Encoder readings of positions ``y`` (N, 3), m: stationary AR(1) noise (innovation
    ``SIGMA``, coefficient ``PHI``) rounded to encoder counts."""
    e = np.empty_like(y)
    e[0] = SIGMA / np.sqrt(1 - PHI**2) * rng.standard_normal(y.shape[1])
    w = SIGMA * rng.standard_normal(y.shape)
    for k in range(1, y.shape[0]):
        e[k] = PHI * e[k - 1] + w[k]
    return np.round((y + e) / M_PER_COUNT) * M_PER_COUNT


def make_replicate(rng, n: int = 2000):
    """Records and their truths.

    Returns
    -------
    records : list of Experiment
    truth : dict
        ``g_v`` and ``v0`` per record, ``mu_gv`` and the shared physics.
    """
    out, gains, offsets = [], [], []
    for name, v in inputs(n).items():
        g = MU_GV * np.exp(TAU_GV * rng.standard_normal())
        v0 = V0_SD * rng.standard_normal()
        y = simulate(np.r_[g, PHYSICS], v + v0)
        out.append(Experiment(np.arange(n) * DT, v, measure(y, rng), name=name))
        gains.append(g)
        offsets.append(v0)
    return out, {"g_v": gains, "v0": offsets, "mu_gv": MU_GV, "physics": PHYSICS}


def true_modes():
    """Undamped natural frequencies (rad/s) and modal damping ratios of the truth."""
    from bayesmodal.inference.propagate import propagate_modes
    from bayesmodal.model.system import LinearModel, Rig

    ms = propagate_modes(LinearModel(Rig(SPRINGS), "free"), np.r_[MU_GV, PHYSICS][None],
                         methods=("eig",))
    return ms.omega_rad_s[0], ms.zeta[0]


QUANTITIES = ("m1", "m2", "m3", "omega_1", "omega_2", "omega_3", "zeta_1", "zeta_2",
              "zeta_3", "mu_gv")


def _inside(draws, truth):
    lo, hi = np.quantile(draws, [0.05, 0.95])
    return bool(lo <= truth <= hi)


def replicate(seed: int, *, n_samples: int = 2000, steps: int = 3000, walkers: int = 56
              ) -> dict:
    """One replicate: which of ``QUANTITIES`` each analysis's 90 % interval contains."""
    import time
    import warnings

    from bayesmodal.inference import sample_posterior
    from bayesmodal.inference.propagate import propagate_modes
    from bayesmodal.inference.record_layout import RecordLayout
    from bayesmodal.model.system import LinearModel, Rig

    rng = np.random.default_rng(seed)
    recs, truth = make_replicate(rng, n_samples)
    omega, zeta = true_modes()
    model = LinearModel(Rig(SPRINGS), "free")
    t_true = {"m1": PHYSICS[0], "m2": PHYSICS[1], "m3": PHYSICS[2],
              "mu_gv": MU_GV,
              **{f"omega_{i + 1}": omega[i] for i in range(3)},
              **{f"zeta_{i + 1}": zeta[i] for i in range(3)}}
    out = {"seed": seed, "truth_gains": truth["g_v"]}
    # the truth draws a gain and an offset per record: both from populations
    hier = RecordLayout({"g_v": "hierarchical", "v0": "hierarchical"})
    for label, exps, layout in (("joint", recs, hier), ("single", recs[:1], None)):
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            run = sample_posterior(exps, model, noise="ar1", layout=layout,
                                   n_walkers=walkers, n_steps=steps, burn=steps // 2,
                                   rng=seed, warn=False)
        d = run.flat_draws
        names = run.names
        mech = run.likelihood.split(d)[0]
        ms = propagate_modes(model, mech, methods=("eig",))
        got = {nm: d[:, names.index(nm)] for nm in ("m1", "m2", "m3")}
        got["mu_gv"] = d[:, names.index("mu_g_v" if layout else "g_v")]
        for i in range(3):
            got[f"omega_{i + 1}"] = ms.omega_rad_s[:, i]
            got[f"zeta_{i + 1}"] = ms.zeta[:, i]
        out[label] = {q: _inside(got[q], t_true[q]) for q in QUANTITIES}
        out[label + "_intervals"] = {
            q: [float(x) for x in np.quantile(got[q], [0.05, 0.5, 0.95])] + [float(t_true[q])]
            for q in QUANTITIES}
        out[label + "_diag"] = {"max_rhat": float(run.diagnostics.max_rhat),
                                "min_ess": float(run.diagnostics.min_ess),
                                "seconds": time.perf_counter() - t0}
    return out
