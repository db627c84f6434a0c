"""Task knowledge lives in the task: what each task of the suite declares, and that nothing outside
the tasks names one."""

import ast
import pathlib

import pytest

from rmac_mj import tasks
from rmac_mj.solvers import SOLVERS
from rmac_mj.tasks import NOTHING_KNOWN, TaskKnowledge

PACKAGE = pathlib.Path(__file__).resolve().parents[2] / "rmac_mj"


def _code_strings(path: pathlib.Path) -> list[tuple[int, str]]:
    """The string constants of a module's code: docstrings (of modules, classes, functions and
    attributes: prose and examples) left out."""
    tree = ast.parse(path.read_text())
    docstrings = {
        id(node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
    }
    return [
        (node.lineno, node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and id(node) not in docstrings
    ]


@pytest.mark.slow
def test_nothing_outside_the_tasks_names_a_task_of_the_suite():
    """No code under rmac_mj/ (docstrings aside) holds a domain of the suite, or one of its task
    names as a whole string: what is task-specific comes from the task (``tasks.knowledge``,
    ``tasks.DEFAULT_TASK``)."""
    task_names = {t for ts in tasks.TASKS_BY_DOMAIN.values() for t in ts}
    # The public panel is a fixed list of named tasks: naming them is what that module is for.
    exempt = {PACKAGE / "experiments" / "panel.py"}
    found = [
        f"{path.relative_to(PACKAGE.parent)}:{line}: {text!r}"
        for path in sorted(set(PACKAGE.rglob("*.py")) - exempt)
        for line, text in _code_strings(path)
        if any(domain in text for domain in tasks.TASKS_BY_DOMAIN) or text in task_names
    ]
    assert not found, "\n".join(found)


@pytest.mark.parametrize("domain, task", tasks.ALL_TASKS)
def test_every_task_declares_what_the_experiments_can_use(domain, task):
    knowledge = tasks.knowledge(domain, task)
    assert isinstance(knowledge, TaskKnowledge)
    if knowledge.optimum is not None:
        assert knowledge.optimum.method in SOLVERS
    env = tasks.load(domain, task, task_kwargs={"random": 0})
    for name, demonstrator in knowledge.demonstrators.items():
        controller = demonstrator.controller(env)
        x = env.physics.state()
        assert controller(x).shape == env.action_spec().shape, name
        assert demonstrator.action_noise >= 0
    assert knowledge.plot_hints.return_margin > 0


def test_the_default_task_and_a_task_without_knowledge():
    assert tasks.DEFAULT_TASK in tasks.ALL_TASKS
    assert tasks.knowledge(*tasks.DEFAULT_TASK).optimum is not None  # the paper's: -748.1
    assert tasks.knowledge("dc_pendulum", "balance").optimum is None  # random starts
    with pytest.raises(ValueError, match="unknown task_name"):
        tasks.knowledge("dc_pendulum", "spin")
    assert NOTHING_KNOWN.demonstrators == {} and NOTHING_KNOWN.optimum is None
    with pytest.raises(ValueError, match="no demonstrator 'demo' for x; available: none"):
        NOTHING_KNOWN.demonstrator("demo", "x")
