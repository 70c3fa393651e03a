"""The rig and how it moves: the lowest layer of bayesmodal.

- ``system``: the linear model ``M x'' + C x' + K x = b v`` with free or proportional
  damping (it re-exports the rig and its elements);
- ``rig``: the rig description (``Rig``: carts, springs, dampers, drive, sensors, clamps,
  ties), checked step by step in ``_rig_checks``; ``elements``: the carts, springs,
  dampers, drive and sensors it is built of; ``_param_layout``: where each parameter of
  a general rig goes in the matrices;
- ``rigs``: rig descriptions as TOML files and the shipped presets;
- ``simulate``: the exact zero-order-hold simulator of the linear model, with
  ``discretize`` (the exact discretisation, a record's steps), ``_modal_form`` and
  ``_chunks`` (the modal form of a batch, the loop over the compiled kernels);
- ``effects``: the effects the linear model leaves out (friction, end stop, backlash,
  dead band, ...), one module each, behind one registry (``EXTENSIONS``);
- ``kernels``, ``_kernels``, ``_qep``: compiled array code only.

It imports nothing from the layers above it (data, fitting, inference, diagnosis, runs,
plots, the command line): ``tests/test_layers.py`` reads the imports from the source.
"""

from .discretize import discretize_zoh
from .effects import EXTENSIONS, EffectLocation, Extension, ParamSpec, get_extension
from .elements import ECP_M_PER_COUNT, FRAME, Cart, Damper, Drive, Sensor, Spring
from .rig import Rig
from .rigs import PRESETS, load_rig, rig_from_toml, rig_to_toml, save_rig
from .simulate import simulate_linear
from .system import LinearModel

__all__ = [
    "Rig", "Cart", "Spring", "Damper", "Drive", "Sensor", "FRAME", "ECP_M_PER_COUNT",
    "LinearModel", "simulate_linear", "discretize_zoh", "load_rig", "save_rig",
    "rig_from_toml", "rig_to_toml", "PRESETS", "EXTENSIONS", "Extension", "ParamSpec",
    "EffectLocation", "get_extension",
]
