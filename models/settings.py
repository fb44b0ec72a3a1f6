"""Settings dataclasses from and to YAML, with the errors of :mod:`models.config`.

Every run, study and solver setting is a frozen dataclass whose defaults are written once,
in the dataclass. :func:`settings_from_fields` reads one from a YAML mapping field by field
(types from the dataclass' annotations: numbers, integers, strings, booleans, fixed-length
number lists, optional values, nested settings), rejecting unknown and mistyped fields with
the file and the field's dotted path; the dataclass' own checks (``__post_init__``) then
run, and their complaint is reported against the file. :func:`settings_to_dict` writes one
back, so a run's resolved settings (``config.yaml``) replay it exactly.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml

from models.config import ConfigError, Fields

T = TypeVar("T")
_MISSING = object()


def _unwrap_optional(hint: Any) -> tuple[Any, bool]:
    """(the type inside ``X | None``, True) or (hint, False)."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(hint)) == 2:
            return args[0], True
    return hint, False


def _read(fields: Fields, name: str, hint: Any, default: Any) -> Any:
    """Field ``name`` of type ``hint``; ``default`` is ``_MISSING`` for a required one."""
    hint, optional = _unwrap_optional(hint)
    if optional and fields.has(name) and fields.raw(name) is None:
        return None
    extra = () if default is _MISSING else (default,)
    if dataclasses.is_dataclass(hint):
        return settings_from_fields(hint, fields.sub(name),
                                    base=None if default is _MISSING else default)
    if hint is bool:
        return fields.boolean(name, *extra)
    if hint is int:
        return fields.number(name, *extra, integer=True)
    if hint is float:
        return fields.number(name, *extra)
    if hint is str:
        return fields.string(name, *extra)
    if typing.get_origin(hint) is tuple:
        args = typing.get_args(hint)
        if args and args[0] is float and (all(a is float for a in args) or
                                          (len(args) == 2 and args[1] is Ellipsis)):
            length = len(default) if default not in (_MISSING, None) else len(args)
            return fields.vector(name, length, *extra)
        if len(args) == 2 and args[1] is Ellipsis and args[0] is str:
            return fields.string_list(name, *extra)
        inner = typing.get_args(args[0]) if args else ()
        if len(args) == 2 and args[1] is Ellipsis and inner and all(a is float for a in inner):
            return _vectors(fields, name, len(inner), default)
    raise TypeError(f"settings field {name!r}: type {hint!r} is not readable from YAML")


def _vectors(fields: Fields, name: str, length: int, default: Any) -> tuple:
    """A non-empty list of ``length``-number lists (e.g. several planar poses)."""
    value = fields.raw(name) if default is _MISSING else fields.raw(name, default)
    if value is default:
        return default
    if not isinstance(value, list) or not value:
        raise fields.error(name, f"expected a non-empty list of {length}-number lists, "
                                 f"got {value!r}")
    rows = Fields({f"{name}[{i}]": v for i, v in enumerate(value)}, fields.source,
                  fields.prefix)
    return tuple(rows.vector(f"{name}[{i}]", length) for i in range(len(value)))


def settings_from_fields(cls: type[T], fields: Fields, *, base: T | None = None) -> T:
    """A ``cls`` from a YAML mapping; absent fields keep ``base``'s values (default: the
    dataclass defaults).

    Raises:
        ConfigError: a missing required, unknown, mistyped or out-of-range field (named
            with its dotted path), or settings the dataclass itself rejects.
    """
    hints = typing.get_type_hints(cls)
    values = {}
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        if base is not None:
            default = getattr(base, f.name)
        elif f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = _MISSING
        if fields.has(f.name) or default is _MISSING:
            values[f.name] = _read(fields, f.name, hints[f.name], default)
        else:
            values[f.name] = default
    fields.done()
    try:
        return cls(**values)
    except (ValueError, TypeError) as err:
        raise ConfigError(fields.source, fields.prefix, str(err)) from err


def check_ranges(settings: Any, *, positive: tuple[str, ...] = (),
                 non_negative: tuple[str, ...] = (), counts: tuple[str, ...] = (),
                 at_most: Mapping[str, float] | None = None) -> None:
    """Reject fields of the settings dataclass ``settings`` out of their range: each named
    field's value, or every element of a tuple value (a ``None`` is skipped: an optional
    setting left unset), must be > 0 (``positive``: sizes, speeds, time steps), >= 0
    (``non_negative``: noise levels, weights), an integer >= 1 (``counts``: trials,
    particles, samples), and at most ``at_most[name]`` in magnitude (the physical or
    practical ceiling, in the field's own unit, that catches a 1e12 m/s hand speed which
    would otherwise load and then run absurdly). NaN fails every test.

    Raises:
        ValueError: naming the first offending field and its value (which
            :func:`settings_from_fields` reports against the file).
    """
    rules = [(positive, "> 0", lambda v: v > 0), (non_negative, ">= 0", lambda v: v >= 0),
             (counts, "an integer >= 1", lambda v: float(v).is_integer() and v >= 1)]
    rules += [((name,), f"at most {bound:g} in magnitude", lambda v, b=bound: abs(v) <= b)
              for name, bound in (at_most or {}).items()]
    for names, wanted, holds in rules:
        for name in names:
            value = getattr(settings, name)
            values = np.ravel(value) if isinstance(value, tuple) else (value,)
            if not all(v is None or holds(v) for v in values):
                raise ValueError(f"{name} must be {wanted}, got {value!r}")


def load_settings(cls: type[T], path: Path | str) -> T:
    """Read a ``cls`` from the YAML file ``path`` (see :func:`settings_from_fields`)."""
    return settings_from_fields(cls, Fields.from_file(Path(path)))


def settings_to_dict(settings: Any) -> dict:
    """A settings dataclass as plain YAML-ready data (tuples become lists)."""
    def plain(value):
        if dataclasses.is_dataclass(value):
            return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)
                    if f.init}
        if isinstance(value, tuple | list):
            return [plain(v) for v in value]
        if isinstance(value, Path):
            return str(value)
        return value
    return plain(settings)


def write_settings(settings: Any, path: Path, *, comment: str = "") -> None:
    """Write ``settings`` as YAML to ``path`` (a leading ``# comment`` line if given)."""
    header = f"# {comment}\n" if comment else ""
    path.write_text(header + yaml.safe_dump(settings_to_dict(settings), sort_keys=False))
