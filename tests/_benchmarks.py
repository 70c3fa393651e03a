"""Loading a script of ``benchmarks/`` as a module, for the reduced tests of its studies."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def load_benchmark(name: str) -> ModuleType:
    """The module of ``benchmarks/<name>.py`` (registered in ``sys.modules``, where
    dataclasses look their module up while being created)."""
    spec = importlib.util.spec_from_file_location(f"bayesmodal_bench_{name}",
                                                  BENCHMARKS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod
