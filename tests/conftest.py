"""Test-wide set-up: the GL back end must be chosen before mujoco is first imported."""

import rmac_mj  # noqa: F401  (rmac_mj/__init__.py selects the back end; see rmac_mj._gl)

import pytest  # noqa: E402


@pytest.fixture
def toy(monkeypatch):
    """The test-only domain ``toy``/``settle`` (n = 4, m = 2, 0.2 s trials), registered in
    ``rmac_mj.tasks`` for one test (see tests/toy_domain.py)."""
    import toy_domain

    toy_domain.register(monkeypatch)
    return toy_domain


def pytest_collection_modifyitems(config, items):
    """Tests run for a deep-RL baseline (a parameter naming one) are skipped, with the reason, when
    its [baselines] extra is not installed."""
    from rmac_mj.agents import sb3_config

    if sb3_config.available():
        return
    skip = pytest.mark.skip(reason=sb3_config.INSTALL_HINT)
    for item in items:
        callspec = getattr(item, "callspec", None)
        if callspec is not None and any(isinstance(value, str) and value in sb3_config.BASELINES
                                        for value in callspec.params.values()):
            item.add_marker(skip)
