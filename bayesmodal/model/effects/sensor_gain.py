"""Sensors that read a little more or less than their description says: a scale error
of each sensor relative to the first.

Physics: an encoder's metres per count come from the pinion or the strip pitch, an
accelerometer's sensitivity from its calibration sheet; a worn pinion, a different strip
or a stale calibration makes one sensor read ``s_j`` times the true motion.  Only the
ratios between sensors can be told from the records: scaling every sensor alike is the
same as scaling the drive gain and the masses, so the first sensor is the reference and
sensors ``2..n_outputs`` carry ``s_<j>`` (1: as described).  The residual check of the
gain per output (``checks.gain``) points here when the outputs ask for different gains.
The model stays linear and is simulated exactly; ``s_j = 1`` gives the linear model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..system import Rig
from ._base import EffectLocation, Extension, ParamSpec
from ._input import linear_lanes_run
from ._linear import ALL_KINDS


@dataclass(frozen=True)
class SensorGain(Extension):
    """Scale ``s_<j>`` of sensor ``j = 2..n_outputs`` relative to the first (1: as
    described).

    Examples
    --------
    >>> SensorGain().extension_names(Rig())
    ('s_2', 's_3')
    """

    name = "sensor_gain"
    signatures = ("sensor_gain",)
    default_candidate = False
    typical = (1.03, 0.98)
    description = "each sensor after the first reads s_j times the motion (a scale error)"
    exact = True
    sensor_kinds = ALL_KINDS
    validity_rule = "linear part admissible, s_j finite and > 0"
    side = "output"

    def unsupported(self, rig: Rig) -> str | None:
        if rig.n_outputs < 2:
            return (f"{self.name} compares sensors with the first, and this rig has one "
                    "sensor; it needs two or more")
        return None

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return tuple(
            ParamSpec(f"s_{j + 1}", "1", (0.8, 1.25), 1.0,
                      f"scale of sensor {j + 1} (cart {s.cart}) relative to sensor 1", 0.01)
            for j, s in enumerate(rig.sensors) if j > 0)

    def _valid_extension(self, rig, theta_lin, theta_ext):
        return np.all(np.isfinite(theta_ext) & (theta_ext > 0), axis=-1)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, outputs=None):
        return linear_lanes_run(rig, theta_lin, u, dt, x0, outputs=outputs)

    def transform_output(self, rig, theta_ext, y):
        return np.concatenate([y[..., :1], y[..., 1:] * theta_ext[:, None, :]], axis=-1)

    def location_of(self, rig: Rig, theta: np.ndarray) -> EffectLocation:
        """The sensor whose scale is farthest from 1; strength ``|s_j - 1|``."""
        theta = self.check(rig, np.asarray(theta, dtype=float))
        s = np.r_[0.0, np.abs(self.split(rig, theta)[1] - 1.0)]
        j = int(np.argmax(s))
        return EffectLocation("sensor", j, f"sensor {j + 1} (cart {rig.sensors[j].cart})", s)

    def opt_bounds(self, rig):
        q = rig.n_outputs - 1
        return np.full(q, 1e-3), np.full(q, np.inf)

    def start_grid(self, rig: Rig) -> np.ndarray:
        """As described, and every sensor after the first 2 % high or low."""
        q = rig.n_outputs - 1
        return np.array([np.full(q, v) for v in (1.0, 1.02, 0.98)])
