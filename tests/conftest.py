import matplotlib

matplotlib.use("Agg")

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def shipped_flight(repo_root, tmp_path_factory):
    """``get(name)`` -> (scenario, truth, truth path) of a shipped scenario; flights are cached
    in a per-session folder unless NAVSIM_CACHE is set."""
    import os

    from navsim.runner import cached_flight
    from navsim.scenario import load_scenario
    os.environ.setdefault("NAVSIM_CACHE", str(tmp_path_factory.mktemp("cache")))

    def get(name):
        scenario = load_scenario(repo_root / "scenarios" / f"{name}.yaml")
        truth, path, _ = cached_flight(scenario.flight)
        return scenario, truth, path
    return get


@pytest.fixture
def assert_scenario_error():
    """``check(data, key, words)``: parsing the scenario mapping ``data`` raises a ScenarioError
    that names ``bad.yaml``, the key path ``key`` and contains ``words``."""
    def check(data, key, words):
        from navsim.errors import ScenarioError
        from navsim.scenario import parse_scenario
        with pytest.raises(ScenarioError) as exc:
            parse_scenario(data, "bad.yaml")
        assert f"bad.yaml: {key}:" in str(exc.value) and words in str(exc.value), str(exc.value)
    return check
