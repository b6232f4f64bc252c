"""Pieces of JSON Schema shared by the modules that declare a part of the scenario schema
(:mod:`navsim.experiment.schema` assembles them; measurement models declare their keys')."""

from __future__ import annotations

NUM = {"type": "number"}
POS = {"type": "number", "exclusiveMinimum": 0}
#: a non-negative number, or three
VEC3 = {"oneOf": [{"type": "number", "minimum": 0},
                  {"type": "array", "items": {"type": "number", "minimum": 0}, "minItems": 3, "maxItems": 3}]}


#: a measurement model's entry: defined once under the schema's ``$defs`` (every registered type,
#: plug-ins' included, when the schema is made)
MEASUREMENT = {"$ref": "#/$defs/measurement"}


def merge_properties(props: dict, new: dict) -> None:
    """Add ``new``'s properties to ``props`` in place; a key both declare differently takes
    either form (``anyOf``)."""
    for key, sub in new.items():
        have = props.get(key)
        if have is None:
            props[key] = sub
        elif have != sub and sub not in have.get("anyOf", ()):
            props[key] = {"anyOf": [*have.get("anyOf", [have]), sub]}


def obj(props: dict, required=(), description: str | None = None) -> dict:
    """An object with exactly the keys ``props`` (``required`` among them)."""
    out = {"type": "object", "properties": props, "additionalProperties": False}
    if required:
        out["required"] = list(required)
    if description:
        out["description"] = description
    return out
