"""Typed, frozen configuration objects that reject unknown fields.

Every option of the package — a scenario's parameters, a simulation's settings, later a model's
and a training run's — is a :func:`frozen_config` class: a frozen, keyword-only dataclass whose
constructor refuses unknown names (listing the valid ones) and whose ``validate`` method checks
ranges once, at construction. The CLI parses its options into the same objects, so a value is
checked the same way wherever it comes from.

Example::

    @frozen_config
    class Solver(Config):
        rtol: float = 1e-10

        def validate(self) -> None:
            check_positive(self, "rtol")

    Solver(rtol=1e-12)          # fine
    Solver(rtool=1e-12)         # ConfigError: unknown parameter 'rtool' for Solver; valid: rtol
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import json
import math
import os
import tomllib
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, TypeVar

from fhnn.errors import ConfigError

C = TypeVar("C", bound="Config")


class Config:
    """Base of all configuration classes (decorate subclasses with :func:`frozen_config`)."""

    #: Name used in error messages; defaults to the class name.
    config_name: ClassVar[str] = ""

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Check value ranges; raise :class:`ConfigError` naming the bad value."""

    @classmethod
    def describe(cls) -> str:
        return cls.config_name or cls.__name__

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))  # type: ignore[arg-type]

    @classmethod
    def from_dict(cls: type[C], values: Mapping[str, Any]) -> C:
        """Build from a mapping, converting strings (from a CLI or a file) to the field types."""
        hints = typing.get_type_hints(cls)
        _reject_unknown(cls, values.keys())
        converted = {k: coerce(hints[k], v, f"{cls.describe()}.{k}") for k, v in values.items()}
        return cls(**converted)

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python (JSON-serialisable) view of every field."""
        return {k: _plain(getattr(self, k)) for k in self.field_names()}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    def replace(self: C, **changes: Any) -> C:
        """A copy with ``changes`` applied (unknown names rejected, values validated)."""
        return type(self).from_dict({**self.to_dict(), **changes})

    def setting_names(self) -> tuple[str, ...]:
        """The dotted names of every leaf setting (``"train.lr"``); nested configurations recurse."""
        names: list[str] = []
        for name in self.field_names():
            value = getattr(self, name)
            if isinstance(value, Config):
                names += [f"{name}.{sub}" for sub in value.setting_names()]
            else:
                names.append(name)
        return tuple(names)

    def with_settings(self: C, settings: Mapping[str, Any]) -> C:
        """A copy with dotted-name ``settings`` applied (``{"train.lr": "1e-3"}``); an unknown name
        is refused with the closest valid one, values are converted and validated."""
        check_setting_names(self, settings)
        return type(self).from_dict(deep_merge(self.to_dict(), nest(settings)))

    def differences(self, other: Config) -> list[str]:
        """Dotted names of the settings whose values differ between ``self`` and ``other``."""
        mine, theirs = flatten(self.to_dict()), flatten(other.to_dict())
        return [
            k for k in dict.fromkeys([*mine, *theirs]) if mine.get(k, _MISSING) != theirs.get(k, _MISSING)
        ]


_MISSING = object()


def nest(settings: Mapping[str, Any]) -> dict[str, Any]:
    """``{"a.b": 1, "c": 2}`` → ``{"a": {"b": 1}, "c": 2}``."""
    out: dict[str, Any] = {}
    for key, value in settings.items():
        parts = key.split(".")
        node = out
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ConfigError(f"setting {key!r} conflicts with a value given for {part!r}")
        if isinstance(node.get(parts[-1]), dict):
            raise ConfigError(f"setting {key!r} names a section, not a value")
        node[parts[-1]] = value
    return out


def flatten(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` → ``{"a.b": 1}`` (the inverse of :func:`nest`)."""
    out: dict[str, Any] = {}
    for key, value in values.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten(value, f"{name}."))
        else:
            out[name] = value
    return out


def deep_merge(base: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with ``overrides`` applied recursively (mappings merged, other values replaced)."""
    out = dict(base)
    for key, value in overrides.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = value
    return out


def read_settings_file(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Settings from a TOML (``.toml``) or JSON file as dotted names: sections become prefixes
    (``[train]`` / ``{"train": {...}}`` with ``lr = 1e-3`` gives ``train.lr``)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"settings file '{path}' does not exist")
    try:
        if path.suffix.lower() == ".toml":
            with path.open("rb") as f:
                values = tomllib.load(f)
        elif path.suffix.lower() == ".json":
            values = json.loads(path.read_text(encoding="utf-8"))
        else:
            raise ConfigError(f"settings file '{path}' must end in .toml or .json")
    except (tomllib.TOMLDecodeError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"settings file '{path}' is not valid {path.suffix[1:].upper()}: {exc}") from None
    if not isinstance(values, Mapping):
        raise ConfigError(
            f"settings file '{path}' must hold a table of settings, got {type(values).__name__}"
        )
    return flatten(values)


def get_setting(config: Config, name: str) -> Any:
    """The value of the dotted setting ``name`` of ``config``."""
    value: Any = config
    for part in name.split("."):
        value = getattr(value, part)
    return value


def check_setting_names(config: Config, names: typing.Iterable[str]) -> None:
    """Raise :class:`ConfigError` for the first of ``names`` that is not a setting of ``config``,
    suggesting the closest valid dotted name."""
    valid = config.setting_names()
    for name in names:
        if name in valid:
            continue
        same_leaf = [v for v in valid if v.rsplit(".", 1)[-1] == name.rsplit(".", 1)[-1]]
        close = same_leaf or difflib.get_close_matches(name, valid, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        section = name.rsplit(".", 1)[0] + "." if "." in name else ""
        listed = [v for v in valid if section and v.startswith(section)] or list(
            dict.fromkeys(v.split(".")[0] + (".*" if "." in v else "") for v in valid)
        )
        raise ConfigError(
            f"unknown setting {name!r} for {config.describe()}{hint}; valid: {', '.join(listed)}"
        )


def frozen_config(cls: type[C]) -> type[C]:
    """Make ``cls`` a frozen, keyword-only dataclass whose constructor rejects unknown fields."""
    cls = dataclasses.dataclass(frozen=True, kw_only=True)(cls)
    init = cls.__init__

    @functools.wraps(init)
    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        if args:
            raise ConfigError(f"{cls.describe()} takes keyword arguments only, got {len(args)} positional")
        _reject_unknown(cls, kwargs.keys())
        init(self, **kwargs)

    cls.__init__ = __init__  # type: ignore[method-assign]
    return cls


def _reject_unknown(cls: type[Config], names: typing.Iterable[str]) -> None:
    valid = cls.field_names()
    for name in names:
        if name not in valid:
            close = difflib.get_close_matches(name, valid, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ConfigError(
                f"unknown parameter {name!r} for {cls.describe()}{hint}; valid: {', '.join(valid)}"
            )


def coerce(hint: Any, value: Any, what: str) -> Any:
    """Convert ``value`` (possibly a string from the command line) to the type ``hint``.

    Raises:
        ConfigError: a value that is not of the type, naming ``what``.
    """
    if isinstance(hint, type) and issubclass(hint, Config):
        return _section(hint, value, what)
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return _union(typing.get_args(hint), value, what)
    if origin is typing.Literal:
        return _literal(typing.get_args(hint), value, what)
    if origin is tuple:
        return _tuple(typing.get_args(hint), value, what)
    scalar = _SCALARS.get(hint)
    return scalar(value, what) if scalar is not None else value


def _section(hint: type[Config], value: Any, what: str) -> Config:
    if isinstance(value, hint):
        return value
    if isinstance(value, Mapping):
        return hint.from_dict(value)
    raise ConfigError(f"{what} must be a section of settings, got {value!r}")


def _union(args: tuple[Any, ...], value: Any, what: str) -> Any:
    none = value is None or (isinstance(value, str) and value.lower() in ("none", "null"))
    if none and type(None) in args:
        return None
    errors = []
    for arg in args:
        if arg is type(None):
            continue
        try:
            return coerce(arg, value, what)
        except ConfigError as exc:
            errors.append(str(exc))
    raise ConfigError(errors[0] if errors else f"{what}: bad value {value!r}")


def _literal(args: tuple[Any, ...], value: Any, what: str) -> Any:
    if value not in args:
        raise ConfigError(f"{what} must be one of {', '.join(map(repr, args))}, got {value!r}")
    return value


def _tuple(args: tuple[Any, ...], value: Any, what: str) -> tuple[Any, ...]:
    if isinstance(value, str):
        try:
            value = json.loads(value)
        except json.JSONDecodeError:
            value = [v for v in value.split(",") if v.strip()]
    if not isinstance(value, list | tuple):
        raise ConfigError(f"{what} must be a list, got {value!r}")
    if len(args) == 2 and args[1] is Ellipsis:
        return tuple(coerce(args[0], v, what) for v in value)
    if args and len(args) != len(value):
        raise ConfigError(f"{what} must have {len(args)} entries, got {len(value)}")
    return tuple(coerce(a, v, what) for a, v in zip(args, value, strict=False)) if args else tuple(value)


#: The words a boolean setting takes (case-insensitive), and what each means.
_BOOLEAN_WORDS = {"true": True, "1": True, "yes": True, "on": True}
_BOOLEAN_WORDS.update({"false": False, "0": False, "no": False, "off": False})


def _bool(value: Any, what: str) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.lower() in _BOOLEAN_WORDS:
        return _BOOLEAN_WORDS[value.lower()]
    raise ConfigError(f"{what} must be true or false, got {value!r}")


def _int(value: Any, what: str) -> int:
    if isinstance(value, bool):
        raise ConfigError(f"{what} must be an integer, got {value!r}")
    try:
        as_float = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be an integer, got {value!r}") from None
    if not as_float.is_integer():
        raise ConfigError(f"{what} must be an integer, got {value!r}")
    return int(as_float)


def _float(value: Any, what: str) -> float:
    if isinstance(value, bool):
        raise ConfigError(f"{what} must be a number, got {value!r}")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(out):
        raise ConfigError(f"{what} must be finite, got {value!r}")
    return out


def _str(value: Any, what: str) -> str:
    if not isinstance(value, str):
        raise ConfigError(f"{what} must be a string, got {value!r}")
    return value


#: Converters of the scalar types a setting may have.
_SCALARS: dict[Any, Any] = {bool: _bool, int: _int, float: _float, str: _str}


def _plain(value: Any) -> Any:
    if isinstance(value, Config):
        return value.to_dict()
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    return value


def _get(obj: Config, name: str) -> Any:
    return getattr(obj, name)


def check_positive(obj: Config, *names: str) -> None:
    """Raise unless every named field is a finite number > 0."""
    for name in names:
        value = _get(obj, name)
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ConfigError(f"{obj.describe()}: {name} must be > 0, got {value!r}")


def check_nonnegative(obj: Config, *names: str) -> None:
    """Raise unless every named field is a finite number >= 0."""
    for name in names:
        value = _get(obj, name)
        if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
            raise ConfigError(f"{obj.describe()}: {name} must be >= 0, got {value!r}")


def check_interval(obj: Config, low: str, high: str) -> None:
    """Raise unless field ``low`` <= field ``high``."""
    if _get(obj, low) > _get(obj, high):
        raise ConfigError(
            f"{obj.describe()}: {low} ({_get(obj, low)!r}) must not exceed {high} ({_get(obj, high)!r})"
        )
