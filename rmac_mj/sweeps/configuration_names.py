"""Names of a sweep's configurations from their swept values: each value's label, each key's
shortest distinct suffix, a directory name that is safe on any file system."""

from __future__ import annotations

import re
from typing import Any


def is_number(value: Any) -> bool:
    """Whether ``value`` is a number (a bool is not): a swept axis of numbers is drawn to scale."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def value_label(value: Any) -> str:
    if isinstance(value, list):
        return ",".join(value_label(v) for v in value)
    if isinstance(value, dict):
        return "+".join(f"{k}-{value_label(v)}" for k, v in value.items())
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def short_names(keys: list[str]) -> dict[str, str]:
    """Each key's shortest dotted suffix that no other key shares (``rmac.exploration.sigma`` ->
    ``sigma``; with ``s-ac.exploration.sigma`` beside it, ``rmac.exploration.sigma`` stays whole)."""
    names = {}
    for key in keys:
        parts = key.split(".")
        for size in range(1, len(parts) + 1):
            suffix = ".".join(parts[-size:])
            if sum(other.split(".")[-size:] == parts[-size:] for other in keys) == 1:
                break
        names[key] = suffix
    return names


_UNSAFE = re.compile(r"[^A-Za-z0-9._,=+-]")


def configuration_name(variant: str | None, values: dict[str, Any], short: dict[str, str]) -> str:
    """A directory name from the swept values: ``[variant__]sigma=0.5__period=3``."""
    parts = ([variant] if variant is not None else []) + [
        f"{short[key]}={value_label(value)}" for key, value in values.items()
    ]
    name = _UNSAFE.sub("_", "__".join(parts)) or "base"
    return name.lstrip(".") or "base"
