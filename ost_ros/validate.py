"""Strict checks for parsed YAML/JSON documents; every failure names the field it concerns."""

from __future__ import annotations

from typing import Any

from ost_ros.errors import OstError


class FieldError(OstError):
    """Invalid input; the message starts with the offending field, e.g. ``objects[3].location``."""


def integer(value: Any, where: str, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise FieldError(f"{where}: expected an integer, got {value!r}")
    if minimum is not None and value < minimum:
        raise FieldError(f"{where}: must be at least {minimum}, got {value}")
    return value


def cell(value: Any, where: str) -> tuple[int, int]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise FieldError(f"{where}: expected [x, y], got {value!r}")
    return (integer(value[0], where + "[0]"), integer(value[1], where + "[1]"))


def mapping(value: Any, where: str, allowed: tuple[str, ...], required: tuple[str, ...] = ()) -> dict:
    if not isinstance(value, dict):
        raise FieldError(f"{where}: expected a mapping, got {type(value).__name__}")
    for key in value:
        if key not in allowed:
            raise FieldError(f"{where}: unknown key {key!r} (allowed: {', '.join(allowed)})")
    for key in required:
        if key not in value:
            raise FieldError(f"{where}: missing key {key!r}")
    return value


def listing(value: Any, where: str) -> list:
    if not isinstance(value, list):
        raise FieldError(f"{where}: expected a list, got {type(value).__name__}")
    return value
