"""The package's layers read downward: no module imports from a layer above its own.

The layers (``docs/architecture.md``), lowest first; a package may import from any lower layer,
never from a higher one nor from another package of its own layer. Every import counts, also
the ones inside functions.
"""

from __future__ import annotations

import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "thrombojax"

LAYERS: dict[str, int] = {
    "types": 0, "errors": 0, "study": 0, "xla_options": 0, "<root>": 0,
    "units": 1,
    "io": 2, "graph": 2,
    "plotting": 3,
    "sim": 4, "data": 4,
    "models": 5,
    "simulator": 6,
    "train": 7,
    "eval": 8,
    "experiments": 9,
    "cli": 10, "__main__": 11,
}  # fmt: skip


def _unit(module: str) -> str:
    """``thrombojax.eval.bench`` -> ``eval``; ``thrombojax`` -> ``<root>``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "<root>"


def _imports(path: pathlib.Path) -> list[tuple[int, str]]:
    """(line, imported thrombojax unit) of every import in a file, at any depth."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module == "thrombojax":  # from thrombojax import study / __version__
                found += [(node.lineno, a.name if a.name in LAYERS else "<root>")
                          for a in node.names]
            elif node.module.startswith("thrombojax."):
                found.append((node.lineno, _unit(node.module)))
        elif isinstance(node, ast.Import):
            found += [(node.lineno, _unit(a.name)) for a in node.names
                      if a.name.split(".")[0] == "thrombojax"]
    return found


def _violations() -> list[str]:
    bad = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        source = rel.parts[0].removesuffix(".py") if len(rel.parts) > 1 else rel.stem
        if source == "__init__":
            continue  # the lazy public facade re-exports from every layer by name only
        if source not in LAYERS:
            bad.append(f"{rel}: package '{source}' has no layer in tests/test_layering.py")
            continue
        for line, target in _imports(path):
            if target not in LAYERS:
                bad.append(f"{rel}:{line}: imports unknown unit '{target}'")
            elif target != source and LAYERS[target] >= LAYERS[source]:
                bad.append(f"{rel}:{line}: '{source}' (layer {LAYERS[source]}) imports "
                           f"'{target}' (layer {LAYERS[target]})")
    return bad


def test_imports_read_downward():
    assert _violations() == []


def test_checker_finds_an_upward_import(tmp_path, monkeypatch):
    """The checker itself fails on an upward import (train -> eval) and a sideways one."""
    pkg = tmp_path / "thrombojax"
    (pkg / "train").mkdir(parents=True)
    (pkg / "sim").mkdir()
    (pkg / "train" / "loop.py").write_text("def f():\n    from thrombojax.eval.bench import b\n")
    (pkg / "sim" / "x.py").write_text("import thrombojax.data.batching\n")
    monkeypatch.setitem(globals(), "PACKAGE", pkg)
    bad = _violations()
    assert any("'train' (layer 7) imports 'eval'" in b for b in bad)
    assert any("'sim' (layer 4) imports 'data'" in b for b in bad)


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: p.name)
def test_modules_stay_small(path):
    """Modules stay under 400 lines."""
    assert len(path.read_text().splitlines()) <= 400, path


def test_experiment_configs_load():
    """Every config in experiments/configs is a TrainConfig that `thrombojax train` accepts."""
    from thrombojax.train.config import TrainConfig, load_config_file

    configs = sorted((PACKAGE.parent / "experiments" / "configs").glob("*.json"))
    assert configs
    for path in configs:
        assert isinstance(load_config_file(path), TrainConfig), path
