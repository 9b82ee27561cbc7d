"""Model parameters as frozen dataclasses, overridable from a TOML file.

Overrides are checked against the dataclass: an unknown key or a value of the wrong
type is refused with a message naming the key, so a typo never silently falls back to a
default.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Mapping

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]


class ConfigError(ValueError):
    """A configuration file or value that cannot be used; the message says which and why."""


def read_toml(path: str | Path) -> dict:
    p = Path(path)
    try:
        return tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"{p}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p}: cannot read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: malformed TOML: {exc}") from None


def _coerce(name: str, default: Any, value: Any) -> Any:
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(f"{name} must be true or false, got {value!r}")
        return value
    if isinstance(default, (int, float)):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{name} must be a number, got {value!r}")
        if isinstance(default, float):
            return float(value)
        if not float(value).is_integer():
            raise ConfigError(f"{name} must be a whole number, got {value!r}")
        return int(value)
    if isinstance(default, str):
        if not isinstance(value, str):
            raise ConfigError(f"{name} must be a string, got {value!r}")
        return value
    if isinstance(default, tuple):
        if not isinstance(value, list) or len(value) != len(default):
            raise ConfigError(f"{name} must be a list of {len(default)} values, got {value!r}")
        return tuple(_coerce(f"{name}[{i}]", d, v) for i, (d, v) in enumerate(zip(default, value)))
    raise ConfigError(f"{name}: cannot be set from a file")


def override(params: Any, values: Mapping[str, Any]) -> Any:
    """A copy of `params` with `values` applied; then its own `check()` runs if present."""
    fields = {f.name: getattr(params, f.name) for f in dataclasses.fields(params)}
    changes = {}
    for key, value in values.items():
        if key not in fields:
            raise ConfigError(f"unknown parameter {key!r}; known: {', '.join(fields)}")
        changes[key] = _coerce(key, fields[key], value)
    new = dataclasses.replace(params, **changes)
    check = getattr(new, "check", None)
    if check is not None:
        check()
    return new


def as_dict(params: Any) -> dict:
    """Plain JSON-ready dict (tuples become lists)."""
    return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(params).items()}
