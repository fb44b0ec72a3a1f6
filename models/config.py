"""Reading the project's YAML data files with errors that name the file and the field.

Every data file (hand, tactile layout, object, scene) is parsed through :class:`Fields`, so
a malformed file fails at load time with a message such as::

    scenes/my_scene.yaml: field 'object.pose.theta_deg': expected a number, got 'ninety'

rather than deep inside numpy or Drake. Unknown keys are rejected too (a typo must not be
silently ignored and replaced by a default).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

ASSETS_DIR = Path(__file__).resolve().parent / "assets"


class ConfigError(ValueError):
    """A data file is missing, unreadable or has a bad field.

    Attributes:
        source: the file (or other origin) the data came from.
        field: dotted path of the offending field, '' for the whole file.
    """

    def __init__(self, source: str, field: str, message: str):
        self.source = source
        self.field = field
        self.message = message
        where = f"{source}: field '{field}'" if field else f"{source}"
        super().__init__(f"{where}: {message}")

    def __reduce__(self):
        """Rebuilt from its three parts, so it crosses a process pool intact."""
        return ConfigError, (self.source, self.field, self.message)


def load_yaml(path: Path) -> dict[str, Any]:
    """Read a YAML mapping from the UTF-8 text file ``path``.

    Raises:
        ConfigError: when the file is missing or unreadable, is not UTF-8 text, is not
            valid YAML (the message gives the file, line and column, 1-based, as an editor
            shows them), or is not a mapping.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(str(path), "", "no such file")
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise ConfigError(str(path), "", f"cannot be read ({err.strerror or err})") from err
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        line, column = _line_column(raw, err.start)
        raise ConfigError(
            str(path), "", f"not UTF-8 text: byte 0x{raw[err.start]:02x} at line {line}, "
            f"column {column} cannot be decoded (save the file as UTF-8)"
        ) from err
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ConfigError(str(path), "", f"not valid YAML: {_yaml_problem(err, text)}") from err
    if not isinstance(data, dict):
        raise ConfigError(str(path), "", "expected a mapping of fields at the top level")
    return data


def _line_column(text: str | bytes, offset: int) -> tuple[int, int]:
    """1-based (line, column) of the character (or byte) at ``offset`` of ``text``."""
    newline = "\n" if isinstance(text, str) else b"\n"
    line_start = text.rfind(newline, 0, offset) + 1
    return text.count(newline, 0, offset) + 1, offset - line_start + 1


def _yaml_problem(err: yaml.YAMLError, text: str) -> str:
    """What PyYAML found wrong and where (1-based line and column), without the name
    ``<unicode string>`` that PyYAML gives a parsed string."""
    if isinstance(err, yaml.reader.ReaderError):
        line, column = _line_column(text, err.position)
        return f"line {line}, column {column}: {err.reason} (character #x{err.character:04x})"
    if isinstance(err, yaml.MarkedYAMLError):
        mark = err.problem_mark or err.context_mark
        problem = err.problem or err.context or "syntax error"
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        context = ""
        if err.context and err.problem:
            context = f" ({err.context}"
            if err.context_mark is not None:
                context += (f" started at line {err.context_mark.line + 1}, "
                            f"column {err.context_mark.column + 1}")
            context += ")"
        return f"{where}{problem}{context}"
    return str(err)


def resolve_asset(kind: str, name_or_path: str | Path) -> Path:
    """Find a data file by built-in name (``models/assets/<kind>/<name>.yaml``) or by path.

    Args:
        kind: asset folder, e.g. ``"scenes"`` or ``"objects"``.
        name_or_path: a built-in name such as ``"empty"``, or a path to a YAML file.

    Raises:
        ConfigError: when neither a built-in asset nor an existing file matches; the
            message lists the built-in names.
    """
    candidate = Path(name_or_path)
    if candidate.suffix in (".yaml", ".yml") or candidate.parent != Path("."):
        if not candidate.is_file():
            raise ConfigError(str(candidate), "", f"no such {kind} file")
        return candidate
    builtin = ASSETS_DIR / kind / f"{name_or_path}.yaml"
    if builtin.is_file():
        return builtin
    raise ConfigError(
        str(name_or_path), "", f"unknown {kind} name; built-in: {', '.join(builtin_names(kind))}"
        " (or pass a path to a .yaml file)"
    )


def relative_to_file(path: Path, name: str) -> str | Path:
    """A name inside a data file that looks like a path (ends in .yaml or has a ``/``),
    taken relative to that file's folder; a built-in name unchanged."""
    if name.endswith((".yaml", ".yml")) or "/" in name:
        candidate = Path(name)
        return candidate if candidate.is_absolute() else path.parent / candidate
    return name


def builtin_names(kind: str) -> list[str]:
    """Names of the built-in data files of one kind (e.g. all scene names)."""
    return sorted(p.stem for p in (ASSETS_DIR / kind).glob("*.yaml"))


_REQUIRED = object()


def _scientific(value: Any) -> Any:
    """``'1.0e8'`` -> ``1e8``; anything else unchanged."""
    if isinstance(value, str) and "e" in value.lower():
        try:
            return float(value)
        except ValueError:
            return value
    return value


class Fields:
    """A typed, validated view of one YAML mapping, remembering where it came from.

    Each accessor removes the key from the set of unread keys; :meth:`done` then rejects
    keys that nobody read (typos, unsupported options).
    """

    def __init__(self, data: Any, source: str, prefix: str = ""):
        if not isinstance(data, dict):
            raise ConfigError(source, prefix, f"expected a mapping, got {type(data).__name__}")
        self._data = data
        self._unread = set(data)
        self.source = source
        self.prefix = prefix

    @classmethod
    def from_file(cls, path: Path) -> Fields:
        return cls(load_yaml(path), str(path))

    def _path(self, name: str) -> str:
        return f"{self.prefix}.{name}" if self.prefix else name

    def error(self, name: str, message: str) -> ConfigError:
        """A :class:`ConfigError` about field ``name`` of this mapping."""
        return ConfigError(self.source, self._path(name), message)

    def keys(self) -> list[str]:
        """The mapping's keys (for mappings whose keys are data, such as named tables)."""
        return [str(k) for k in self._data]

    def has(self, name: str) -> bool:
        return name in self._data

    def _get(self, name: str, default: Any) -> Any:
        self._unread.discard(name)
        if name not in self._data:
            if default is _REQUIRED:
                raise self.error(name, "required field is missing")
            return default
        return self._data[name]

    def raw(self, name: str, default: Any = _REQUIRED) -> Any:
        """The unvalidated value of ``name`` (the caller validates it)."""
        return self._get(name, default)

    def number(
        self,
        name: str,
        default: Any = _REQUIRED,
        *,
        min: float = -math.inf,
        max: float = math.inf,
        integer: bool = False,
    ) -> float:
        """A finite number in [min, max] (an int when ``integer``).

        Strings in scientific notation such as ``1.0e8`` are accepted: PyYAML (YAML 1.1)
        reads them as strings unless written ``1.0e+8``.
        """
        value = self._get(name, default)
        if value is default and default is not _REQUIRED:
            return value
        value = _scientific(value)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(name, f"expected a number, got {value!r}")
        if integer and not isinstance(value, int):
            raise self.error(name, f"expected an integer, got {value!r}")
        if not math.isfinite(value) or not (min <= value <= max):
            raise self.error(name, f"{value!r} is outside the allowed range [{min}, {max}]")
        return int(value) if integer else float(value)

    def vector(
        self,
        name: str,
        length: int,
        default: Any = _REQUIRED,
        *,
        min: float = -math.inf,
        max: float = math.inf,
    ) -> tuple[float, ...]:
        """A list of exactly ``length`` finite numbers, each in [min, max]."""
        value = self._get(name, default)
        if value is default and default is not _REQUIRED:
            return tuple(value)
        if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != length:
            raise self.error(name, f"expected a list of {length} numbers, got {value!r}")
        out = []
        for i, item in enumerate(value):
            if isinstance(item, bool) or not isinstance(item, int | float):
                raise self.error(f"{name}[{i}]", f"expected a number, got {item!r}")
            if not math.isfinite(item) or not (min <= item <= max):
                raise self.error(
                    f"{name}[{i}]", f"{item!r} is outside the allowed range [{min}, {max}]"
                )
            out.append(float(item))
        return tuple(out)

    def string(self, name: str, default: Any = _REQUIRED, *, choices: Sequence[str] = ()) -> str:
        """A string, optionally one of ``choices``."""
        value = self._get(name, default)
        if value is default and default is not _REQUIRED:
            return value
        if not isinstance(value, str):
            raise self.error(name, f"expected a string, got {value!r}")
        if choices and value not in choices:
            raise self.error(name, f"{value!r} is not one of {', '.join(choices)}")
        return value

    def string_list(
        self, name: str, default: Any = _REQUIRED, *, choices: Sequence[str] = ()
    ) -> tuple[str, ...]:
        """A non-empty list of distinct strings, each optionally one of ``choices``."""
        value = self._get(name, default)
        if value is default and default is not _REQUIRED:
            return tuple(value)
        if (not isinstance(value, list) or not value
                or any(not isinstance(v, str) or (choices and v not in choices) for v in value)):
            allowed = f" drawn from {', '.join(choices)}" if choices else ""
            raise self.error(name, f"expected a non-empty list of names{allowed}, got {value!r}")
        if len(set(value)) != len(value):
            raise self.error(name, f"names must be distinct, got {value!r}")
        return tuple(value)

    def boolean(self, name: str, default: Any = _REQUIRED) -> bool:
        value = self._get(name, default)
        if not isinstance(value, bool):
            raise self.error(name, f"expected true or false, got {value!r}")
        return value

    def sub(self, name: str, default: Any = _REQUIRED) -> Fields:
        """The nested mapping ``name`` as its own :class:`Fields`."""
        value = self._get(name, default)
        return Fields(value, self.source, self._path(name))

    def items(self, name: str, default: Any = _REQUIRED) -> list[Fields]:
        """A list of mappings, each as its own :class:`Fields` (``name[i]``)."""
        value = self._get(name, default)
        if not isinstance(value, list):
            raise self.error(name, f"expected a list, got {value!r}")
        return [Fields(item, self.source, self._path(f"{name}[{i}]"))
                for i, item in enumerate(value)]

    def done(self) -> None:
        """Reject any key that was never read."""
        if self._unread:
            name = sorted(self._unread)[0]
            raise self.error(name, "unknown field (check the spelling)")
