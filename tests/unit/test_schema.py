import json

import jsonschema
import pytest
import yaml

from navsim.experiment.schema import scenario_schema, schema_text
from navsim.foundations.config import SafeLoader


def test_published_schema_is_current(repo_root):
    assert (repo_root / "docs" / "scenario.schema.json").read_text() == schema_text(built_in=True)


def test_shipped_scenarios_follow_the_schema(shipped_scenarios):
    schema = scenario_schema()
    for path in shipped_scenarios:
        jsonschema.validate(yaml.load(path.read_text(), Loader=SafeLoader), schema)


@pytest.mark.parametrize("bad", [{"track": "p0", "trak": 1}, {"name": "x"},
                                 {"track": "p0", "montecarlo": {"runs": 0}},
                                 {"track": {"start": {"lat_deg": 1}, "segments": []}}])
def test_schema_rejects_malformed(bad):
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(bad, json.loads(schema_text()))


def test_yaml_reads_off_as_a_string_and_keeps_true_false(tmp_path):
    from navsim.foundations.config import load_yaml
    path = tmp_path / "x.yaml"
    path.write_text("off: [bias]\non: yes\nflag: true\nother: False\nobj: !!python/object:os.system ls\n")
    with pytest.raises(Exception):                 # no object construction (safe loader)
        load_yaml(path)
    path.write_text("off: [bias]\non: yes\nflag: true\nother: False\n")
    assert load_yaml(path) == {"off": ["bias"], "on": "yes", "flag": True, "other": False}
