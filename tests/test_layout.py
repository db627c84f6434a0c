"""The direction of imports where import-linter does not look: tasks/ and models/ live outside
rmac_mj/ in the source tree (pyproject.toml's package-dir), so `lint-imports` does not see them as
part of the package. A task knows no learner, approximator or harness; a model knows nothing."""

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: What each top-level folder may import of the package (as ``rmac_mj.<name>``).
ALLOWED = {"tasks": {"tasks", "models", "_gl"}, "models": {"models"}}


def _imports(path: pathlib.Path) -> set[str]:
    """Every ``rmac_mj.X`` a file imports, at the top or inside a function."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] == "rmac_mj" and len(parts) > 1:
                found.add(parts[1])
    return found - {"__version__"}


@pytest.mark.parametrize("folder", sorted(ALLOWED))
def test_tasks_and_models_import_nothing_above_them(folder):
    wrong = {
        f"{path.relative_to(ROOT)}: rmac_mj.{name}"
        for path in sorted((ROOT / folder).rglob("*.py"))
        for name in _imports(path) - ALLOWED[folder]
    }
    assert not wrong, sorted(wrong)
