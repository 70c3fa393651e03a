"""The rig and how it moves: the lowest layer of bayesmodal.

- ``system``: the rig description (carts, springs, dampers, drive, sensors, clamps, ties)
  and the linear model ``M x'' + C x' + K x = b v`` with free or proportional damping;
- ``rigs``: rig descriptions as TOML files and the shipped presets;
- ``simulate``: the exact zero-order-hold simulator of the linear model;
- ``effects``: the effects the linear model leaves out (friction, end stop, backlash,
  dead band, ...), one module each, behind one registry (``EXTENSIONS``);
- ``kernels``, ``_kernels``, ``_qep``: compiled array code only.

It imports nothing from the layers above it (data, fitting, inference, diagnosis, runs,
plots, the command line): ``tests/test_layers.py`` reads the imports from the source.
"""

from .effects import EXTENSIONS, EffectLocation, Extension, ParamSpec, get_extension
from .rigs import PRESETS, load_rig, rig_from_toml, rig_to_toml, save_rig
from .simulate import discretize_zoh, simulate_linear
from .system import (
    ECP_M_PER_COUNT,
    FRAME,
    Cart,
    Damper,
    Drive,
    LinearModel,
    Rig,
    Sensor,
    Spring,
)

__all__ = [
    "Rig", "Cart", "Spring", "Damper", "Drive", "Sensor", "FRAME", "ECP_M_PER_COUNT",
    "LinearModel", "simulate_linear", "discretize_zoh", "load_rig", "save_rig",
    "rig_from_toml", "rig_to_toml", "PRESETS", "EXTENSIONS", "Extension", "ParamSpec",
    "EffectLocation", "get_extension",
]
