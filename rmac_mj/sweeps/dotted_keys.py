"""Hyperparameters as dotted keys (``"ALGO.FIELD"``) and as nested tables, both ways, and a value
written back as the user wrote it in TOML, for messages."""

from __future__ import annotations

import json
from typing import Any


def nest(flat: dict[str, Any]) -> dict[str, dict]:
    """``{"rmac.exploration.sigma": 0.5}`` -> ``{"rmac": {"exploration": {"sigma": 0.5}}}``."""
    nested: dict[str, Any] = {}
    for key, value in flat.items():
        *parents, last = key.split(".")
        node = nested
        for part in parents:
            node = node.setdefault(part, {})
        node[last] = merge(node[last], value) if isinstance(node.get(last), dict) else value
    return nested


def merge(base: dict, overrides: dict) -> dict:
    """A deep copy of ``base`` with ``overrides`` applied (nested dicts merged, other values replaced)."""
    merged = json.loads(json.dumps(base))
    for key, value in overrides.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = merge(merged[key], value)
        else:
            merged[key] = json.loads(json.dumps(value))
    return merged


def flatten(table: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """TOML dotted keys nest (``rmac.alpha_r = 1`` is ``{"rmac": {"alpha_r": 1}}``): back to
    ``"rmac.alpha_r"``, so a quoted and a bare key mean the same. Inline tables flatten the same way
    (an override of some fields of a nested config)."""
    flat = {}
    for key, value in table.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            flat.update(flatten(value, f"{name}."))
        else:
            flat[name] = value
    return flat


def as_toml(value: Any) -> str:
    """A value as the user wrote it (TOML-like), for messages and names."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(as_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {as_toml(v)}" for k, v in value.items()) + "}"
    return repr(value)
