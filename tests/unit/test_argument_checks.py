"""The declared arguments (:class:`navsim.foundations.config.Argument`) and the bounds a
scenario's numbers are read within: one limit, and the message says it."""

import pytest

from navsim.experiment.scenario import MAX_SEED, parse_scenario
from navsim.foundations.errors import ScenarioError


def _with_seed(seed) -> dict:
    return {"name": "s", "track": "p0", "sensors": {"imu": {"model": "p3_imu"}},
            "estimators": [{"label": "free", "type": "sins"}], "montecarlo": {"runs": 2, "seed": seed}}


def test_a_yaml_seed_is_taken_up_to_its_limit_and_the_message_says_that_limit():
    assert parse_scenario(_with_seed(MAX_SEED), "s.yaml").seed == MAX_SEED
    for seed in (MAX_SEED + 1, 2**64, 2**200):
        with pytest.raises(ScenarioError) as exc:
            parse_scenario(_with_seed(seed), "s.yaml")
        message = str(exc.value)
        assert "montecarlo.seed" in message and str(MAX_SEED) in message, message
        assert "9.0072e+15" not in message and "magnitude" not in message, message
    with pytest.raises(ScenarioError) as exc:
        parse_scenario(_with_seed(-(2**64)), "s.yaml")
    assert ">= 0" in str(exc.value), str(exc.value)
