"""The model layer stands alone: ``bayesmodal.model`` imports nothing from the layers
above it (data, fitting, inference, diagnosis, runs, plots, reports, the command line),
counting imports inside functions; the imports are read from the source with ``ast``."""

import ast
from pathlib import Path

import bayesmodal

PKG = Path(bayesmodal.__file__).parent


def _module(path: Path) -> str:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path: Path) -> set[str]:
    """Every ``bayesmodal`` module a source file imports, anywhere in the file."""
    mod = _module(path)
    package = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.startswith("bayesmodal"):
                out.add(target)
                out.update(f"{target}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("bayesmodal"))
    return out


def test_imports_of_reads_relative_and_deferred_imports(tmp_path):
    # negative control of the reader: a deferred relative import of an upper layer
    src = PKG / "model" / "_probe_layers.py"
    src.write_text("def f():\n    from ..inference import sample_posterior\n")
    try:
        assert "bayesmodal.inference.sample_posterior" in imports_of(src)
    finally:
        src.unlink()


def test_the_model_layer_imports_only_itself_and_the_errors():
    allowed = ("bayesmodal.model", "bayesmodal._errors")
    bad = {}
    for path in sorted((PKG / "model").rglob("*.py")):
        up = sorted(t for t in imports_of(path)
                    if not any(t == a or t.startswith(a + ".") for a in allowed))
        if up:
            bad[_module(path)] = up
    assert not bad, f"bayesmodal.model imports layers above it: {bad}"
