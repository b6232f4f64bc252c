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
