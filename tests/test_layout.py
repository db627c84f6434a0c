"""The layout where import-linter does not look. The direction of imports of tasks/ and models/,
which live outside rmac_mj/ in the source tree (pyproject.toml's package-dir), so `lint-imports`
does not see them as part of the package: a task knows no learner, approximator or harness; a model
knows nothing. And every package's public face: what it offers, in ``__all__``."""

import ast
import importlib
import pathlib
import subprocess
import sys

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


#: Every package, with the public face its ``__init__`` declares in ``__all__``.
PACKAGES = sorted(
    [
        ".".join(("rmac_mj", *path.parent.relative_to(ROOT / "rmac_mj").parts))
        for path in (ROOT / "rmac_mj").glob("*/**/__init__.py")
    ]
    + ["rmac_mj.tasks"]
)


def test_every_package_is_one():
    # A new room is a package with a face: this list grows with it.
    assert PACKAGES == [
        "rmac_mj.agents",
        "rmac_mj.agents.sb3",
        "rmac_mj.approximators",
        "rmac_mj.bench",
        "rmac_mj.cli",
        "rmac_mj.envs",
        "rmac_mj.evaluation",
        "rmac_mj.experiments",
        "rmac_mj.figures",
        "rmac_mj.results",
        "rmac_mj.solvers",
        "rmac_mj.sweeps",
        "rmac_mj.tasks",
        "rmac_mj.videos",
    ]


@pytest.mark.parametrize("name", PACKAGES)
def test_every_package_says_what_it_offers(name):
    package = importlib.import_module(name)
    offered = package.__all__
    assert offered and len(offered) == len(set(offered)), offered
    missing = [entry for entry in offered if not hasattr(package, entry)]
    assert not missing, missing
    # A name on the face never hides one of the package's modules: `from package import module`
    # would hand out the name instead (the package's attribute wins over the module).
    folder = pathlib.Path(package.__file__).parent
    modules = {path.stem for path in folder.glob("*.py")}
    assert not modules & set(offered), sorted(modules & set(offered))


@pytest.mark.slow
def test_the_learners_face_imports_no_learner():
    # The learners are read from their modules on first use: importing the face compiles nothing
    # and imports neither torch nor Stable-Baselines3, whatever a learner's module imports.
    code = (
        "import sys\n"
        "import rmac_mj.agents as agents\n"
        "loaded = sorted(m for m in sys.modules if m.split('.')[0] in ('torch', "
        "'stable_baselines3', 'sb3_contrib') or m in [agents._LEARNERS[c] for c in "
        "agents._LEARNERS])\n"
        "print(loaded)\n"
        "print(agents.RMAC.__module__, agents.SB3SACConfig.__name__)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert done.stdout.splitlines() == ["[]", "rmac_mj.agents.rmac SB3SACConfig"]


def test_the_code_guide_names_what_every_package_offers():
    guide = (ROOT / "docs" / "guide" / "code.md").read_text()
    unnamed = [
        f"{name}.{entry}"
        for name in PACKAGES
        for entry in importlib.import_module(name).__all__
        if f"`{entry}`" not in guide
    ]
    assert not unnamed, unnamed
