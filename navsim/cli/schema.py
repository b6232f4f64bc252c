"""``navsim schema``: the JSON Schema of scenario files, with the installed plug-ins' names."""

from __future__ import annotations

import sys

from navsim.cli.command import Command
from navsim.experiment.schema import schema_text


def handle(args) -> int:
    """Print the schema."""
    sys.stdout.write(schema_text())
    return 0


COMMAND = Command(
    "schema", "print the JSON Schema of scenario files", usage="",
    description="Print the JSON Schema of scenario files for editors, with the estimators and measurement types "
    "of installed plug-ins (docs/scenario.schema.json holds navsim's own); navsim's own validation is stricter.",
    handler=handle)
