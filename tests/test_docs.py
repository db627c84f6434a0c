"""The README and the user guide say what the code does: their links resolve, the commands they quote
parse, and the README's Python snippets run as they stand."""

import pathlib
import re
import shlex

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
GUIDE = sorted((ROOT / "docs" / "guide").glob("*.md"))
PAGES = [README, *sorted((ROOT / "docs").rglob("*.md")), *sorted((ROOT / "models").rglob("*.md"))]


def _relative(path: pathlib.Path) -> str:
    return str(path.relative_to(ROOT))


def _anchors(page: pathlib.Path) -> set[str]:
    """GitHub's anchors of a page's headings: lower case, punctuation dropped, spaces as dashes."""
    headings = re.findall(r"^#+ (.*)$", page.read_text(), re.M)
    return {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-") for h in headings}


def _links(page: pathlib.Path) -> list[str]:
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    return re.findall(r"\]\(([^)\s]+)\)", text)


@pytest.mark.parametrize("page", PAGES, ids=_relative)
def test_every_relative_link_resolves(page):
    broken = []
    for link in _links(page):
        if re.match(r"[a-z]+:", link):  # https:, mailto:
            continue
        target, _, anchor = link.partition("#")
        path = (page.parent / target).resolve() if target else page
        if not path.exists():
            broken.append(link)
        elif anchor and path.suffix == ".md" and anchor not in _anchors(path):
            broken.append(link)
    assert not broken, broken


def _quoted_commands(page: pathlib.Path) -> list[str]:
    """Every `rmac-mj ...` line of the page's bash blocks, continuations joined, comments dropped."""
    commands = []
    for block in re.findall(r"```bash\n(.*?)```", page.read_text(), re.S):
        for line in block.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            for start, word in enumerate(words):
                if word.endswith("rmac-mj"):
                    commands.append(words[start + 1 :])
    return commands


@pytest.mark.parametrize("page", [README, *GUIDE], ids=_relative)
def test_every_quoted_command_parses(page):
    from rmac_mj.cli import build_parser

    commands = _quoted_commands(page)
    for words in commands:
        if not words:
            continue
        # Only the options are checked here: argparse exits on an unknown option or a bad value.
        build_parser().parse_args([w for w in words if w not in {"&&"}])
    if page == README:
        assert len(commands) >= 8  # the set-up's run and the command-line snippet


def test_the_readme_shows_the_test_command_ci_runs():
    # .ci/run takes the line after "# Run the tests" as the test command.
    lines = README.read_text().splitlines()
    command = lines[lines.index("# Run the tests") + 1]
    assert command.startswith("python3 -m venv .venv && ") and "-m pytest" in command
    setup = lines[lines.index("# Run the tests") - 1]
    assert "rmac-mj reproduce" in setup and 'install -c constraints.txt -e ".[dev]"' in setup


def _python_blocks(page: pathlib.Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", page.read_text(), re.S)


def test_the_readmes_environment_snippet_runs():
    environment = _python_blocks(README)[0]
    namespace: dict = {}
    exec(compile(environment, str(README), "exec"), namespace)
    assert namespace["timestep"].last() and np.isfinite(namespace["timestep"].observation["angle"])


@pytest.mark.slow
def test_the_readmes_learner_snippet_runs():
    learner = _python_blocks(README)[1]
    namespace: dict = {}
    exec(compile(learner, str(README), "exec"), namespace)
    returns = namespace["returns"]
    assert len(returns) == 600 and np.all(np.isfinite(returns))
    # 30 simulated minutes of RMAC learn the swing-up: far above the hanging start.
    assert np.mean(returns[-50:]) > np.mean(returns[:10]) + 1000


def test_the_guides_saved_learner_acts_in_a_plain_loop(tmp_path):
    """The learners guide's snippet on a snapshot saved here: the learner it loads acts greedily
    in a plain loop exactly as the learner that was saved."""
    from rmac_mj import tasks
    from rmac_mj.agents import make_agent
    from rmac_mj.results import save_snapshot
    from rmac_mj.rollout import action_space_of, run_trial, state_space_of

    env = tasks.load("dc_pendulum", "swingup")
    spaces = state_space_of(env), action_space_of(env)
    agent = make_agent("rmac", *spaces, seed=0)
    for _ in range(3):
        run_trial(env, agent)
    path = save_snapshot(
        tmp_path / "trial_0003.npz", agent, *spaces, domain="dc_pendulum", task="swingup", trial=3
    )
    (snippet,) = [
        b for b in _python_blocks(ROOT / "docs/guide/learners.md") if "load_snapshot" in b
    ]
    quoted = re.search(r'load_snapshot\("([^"]+)"\)', snippet).group(1)
    namespace: dict = {}
    exec(compile(snippet.replace(quoted, str(path)), "learners.md", "exec"), namespace)
    assert namespace["meta"]["trial"] == 3
    assert namespace["total"] == run_trial(tasks.load("dc_pendulum", "swingup"), agent, learn=False)
