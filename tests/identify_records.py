"""Records of one rig hiding effects, written as lab files for ``identify`` (tests and
benchmark).

The motion comes from the independent reference simulators (tests/reference_sim.py,
``solve_ivp`` on a rig assembled by hand), never from the package's kernels.  Every
record is the same rig (one parameter set drawn from the seed) under a different input:
the pulses and steps of ``hidden_effects.rig_input`` scaled and sign-flipped per record.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from hidden_effects import DT, rig_input
from hidden_layouts import LAYOUTS
from hidden_pairs import Q, counts
from reference_effects import input_chain_ref
from reference_sim import simulate_coulomb_ref, simulate_linear_ref

#: per-record scale of the input (sign: a reversed record)
SCALES = (1.0, -0.8, 0.6, -1.0)


def write_records(folder: Path, layout: str, seed: int, *, n_records: int = 2,
                  n_samples: int = 2400, v_offset: float = 0.0, v_dead: float = 0.0,
                  friction: dict | None = None, stiffness_sd: float = 0.0,
                  noise: bool = True):
    """Write ``n_records`` CSV records (t, v, x1..xn in SI) of one rig into ``folder``.

    Parameters
    ----------
    layout : str
        ``hidden_layouts.LAYOUTS`` key.
    v_offset, v_dead : float
        Amplifier offset and drive dead band, V (0: none).
    friction : dict, optional
        ``{cart number: (Fc, Fs)}`` in N.
    stiffness_sd : float
        Relative sd of a per-record change of every spring (a rig that differs between
        experiments); 0: the same rig in every record.
    noise : bool
        White noise of 0.3-1 count before the rounding to counts; without, a cart at
        rest reads one count, as an encoder held still by friction does.

    Returns
    -------
    paths : list of Path
        The records; ``folder/truth.json`` lists each record's springs (N/m).
    theta_lin : ndarray
        The linear parameters (model order) of the rig, before per-record changes.
    """
    _, ref, base = LAYOUTS[layout]
    rng = np.random.default_rng(seed)
    theta = base * rng.uniform(0.97, 1.03, base.size)
    n = ref.n
    w = np.zeros(2 * n)
    for cart, (fc, fs) in (friction or {}).items():
        w[cart - 1], w[n + cart - 1] = fc, fs
    paths, truth = [], []
    for r in range(n_records):
        u = SCALES[r % len(SCALES)] * rig_input(n_samples)
        v = input_chain_ref(u, v_offset=v_offset, v_dead=v_dead)
        ref_r = ref
        if stiffness_sd:
            ref_r = type(ref)(n, [(a, b, k * (1 + stiffness_sd * rng.standard_normal()))
                                  for a, b, k in ref.springs])
        y = (simulate_coulomb_ref(ref_r, np.r_[theta, w], v, DT) if np.any(w)
             else simulate_linear_ref(ref_r, theta, v, DT))
        y = (counts(y[:, ref.outputs], rng) if noise
             else np.round(y[:, ref.outputs] / Q) * Q)
        t = np.arange(n_samples) * DT
        p = Path(folder) / f"record_{r + 1}.csv"
        head = "t,v," + ",".join(f"x{j + 1}" for j in range(y.shape[1]))
        np.savetxt(p, np.column_stack([t, u, y]), delimiter=",", header=head, comments="")
        paths.append(p)
        truth.append({"record": p.stem, "springs_n_m": [k for _, _, k in ref_r.springs]})
    (Path(folder) / "truth.json").write_text(json.dumps(truth))
    return paths, theta
