"""Bad input, counted (``cmanip bench robustness``): every kind of file a user can pass,
mutated, and what its loader said.

Each file kind starts from valid files (the built-in assets, a configuration written by
the CLI, a generated push log and ``.pomdp``). YAML files are mutated field by field:
every field removed, replaced by a value of the wrong type (text, a list, a mapping,
null), out of range (negative, zero, 1e12) or non-finite (.nan, .inf), and an unknown
field added beside it. Text tables (push logs, ``.pomdp``) are mutated line by line: a
line removed or duplicated, a number replaced by text, nan, inf or an overflowing literal.
Every file is also truncated at several points, given a syntax error, written in UTF-16
and in Latin-1 with a non-ASCII byte, emptied, and replaced by binary noise.

A loader's answer is one of:

- ``clear``: an error the CLI turns into exit code 2 (a ``ValueError``, including
  ``ConfigError`` and the format errors, or an ``OSError``) whose message names the file;
- ``accepted``: the file loaded. Some mutations leave a valid file (an optional field
  removed, a value changed to another legal one); the rest are silent defaults. Each is
  listed so the two can be told apart, and those whose mutation changed a value but whose
  loaded object is identical to the unmutated file's (compared field by field, arrays by
  their bytes) are counted apart as ``ignored``: the loader dropped or overrode the value
  without a word;
- ``other``: any other exception, or an error that does not name the file: what a user
  would see as a traceback or a riddle. Listed with its message.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import math
import re
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np
import yaml

ASSETS = Path(__file__).resolve().parents[1] / "models" / "assets"

WRONG_VALUES = (("text", "not-a-number"), ("list", [1, 2]), ("mapping", {"a": 1}),
                ("null", None), ("negative", -1.0), ("zero", 0), ("huge", 1e12),
                ("nan", math.nan), ("inf", math.inf))
"""The replacements of a YAML field: (name, value)."""

BAD_NUMBERS = ("abc", "nan", "inf", "1e999", "-1")
"""The replacements of a number in a text table."""


@dataclass(frozen=True)
class FileKind:
    """A kind of file and how the project reads it.

    Attributes:
        name: the kind (``object``, ``scene``...).
        suffix: the file name's ending.
        valid: paths of valid files of the kind.
        load: reads a file; raises on a bad one.
        structured: YAML (mutated by field) or a text table (by line).
    """

    name: str
    suffix: str
    valid: tuple
    load: Callable[[Path], object]
    structured: bool = True


@dataclass
class Outcome:
    """Counts and the cases worth reading."""

    tried: int = 0
    clear: int = 0
    accepted: list[str] = field(default_factory=list)
    ignored: list[str] = field(default_factory=list)
    other: list[str] = field(default_factory=list)


def file_kinds(work: Path) -> list[FileKind]:
    """Every kind of file a user can pass to ``cmanip``, with valid examples (generated
    ones written into ``work``)."""
    from cmanip.config import (
        ClosedLoopStudyConfig,
        HandplanStudyConfig,
        LatDespotStudyConfig,
        MpfStudyConfig,
        RunConfig,
        VisuotactileStudyConfig,
        load_config,
        write_config,
    )
    from experiments.configest_study import ConfigestSettings
    from models.arms.spec import ArmSpec
    from models.herb.scene import SceneSpec
    from models.herb.tactile import TactileLayout
    from models.objects import ObjectSpec
    from models.planar.hand import PlanarSensorLayout
    from models.pusher.log import PushLog
    from models.pusher.rig import PusherSliderRig
    from planning.hand.discretization import HandProblemSpec
    from planning.pomdp.benchmarks import tiger
    from planning.pomdp.cassandra import read_pomdp, write_pomdp

    configs = []
    for cls in (RunConfig, ClosedLoopStudyConfig, MpfStudyConfig, HandplanStudyConfig,
                VisuotactileStudyConfig, LatDespotStudyConfig, ConfigestSettings):
        folder = work / f"config_{cls.__name__}"
        folder.mkdir(parents=True, exist_ok=True)
        path = write_config(cls(), folder)
        configs.append(FileKind(f"config:{cls.__name__}", ".yaml", (path,),
                                lambda p, cls=cls: load_config(cls, p)))
    log = work / "push.csv"
    _push_log().write(log)
    pomdp = work / "tiger.pomdp"
    write_pomdp(tiger(), pomdp)

    def assets(folder: str) -> tuple[Path, ...]:
        return tuple(sorted((ASSETS / folder).glob("*.yaml")))

    return [
        FileKind("object", ".yaml", assets("objects"), ObjectSpec.load),
        FileKind("scene", ".yaml", assets("scenes"), SceneSpec.load),
        FileKind("tactile_layout", ".yaml", assets("tactile"), TactileLayout.load),
        FileKind("planar_sensors", ".yaml", assets("planar_sensors"), PlanarSensorLayout.load),
        FileKind("arm", ".yaml", assets("arms"), ArmSpec.load),
        FileKind("problem", ".yaml", assets("problems"), HandProblemSpec.load),
        FileKind("pusher_rig", ".yaml", (ASSETS / "pusher_slider.yaml",), PusherSliderRig.load),
        *configs,
        FileKind("push_log", ".csv", (log,), PushLog.read, structured=False),
        FileKind("pomdp", ".pomdp", (pomdp,), read_pomdp, structured=False),
    ]


def _push_log():
    """A short valid push log: a rod pushing a box straight ahead, seen by the camera."""
    from models.pusher.log import PushLog

    n = 12
    t = np.arange(n) * 0.01
    x = 0.002 * np.arange(n)
    truth = np.column_stack([x, np.zeros(n), np.zeros(n)])
    rods = np.stack([np.column_stack([x - 0.06, np.zeros(n)]),
                     np.column_stack([x - 0.06, np.full(n, -0.1)])], axis=1)
    forces = np.zeros((n, 2, 2))
    forces[:, 0, 0] = 1.5
    return PushLog(t, rods, forces, np.ones(n, bool), truth.copy(), truth,
                   np.full((n, 3), np.nan), "rect1", 0.00475, 0.3, "synthetic")


# ---------------------------------------------------------------------------- mutations

def _paths(node, prefix=()) -> Iterator[tuple]:
    """Every field path of a parsed YAML document (mapping keys and list indices)."""
    items = (node.items() if isinstance(node, dict) else
             enumerate(node) if isinstance(node, list) else ())
    for key, value in items:
        yield (*prefix, key)
        yield from _paths(value, (*prefix, key))


def _set(doc, path, value, *, delete: bool = False):
    out = copy.deepcopy(doc)
    node = out
    for key in path[:-1]:
        node = node[key]
    if delete:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return out


def yaml_mutations(text: str) -> Iterator[tuple[str, Callable[[], bytes]]]:
    """(label, a function making the bytes) of the field-level mutations of a YAML
    document (made on demand: writing YAML is the slow part of a run)."""
    doc = yaml.safe_load(text)
    if not isinstance(doc, (dict, list)):
        return
    for path in _paths(doc):
        where = ".".join(str(k) for k in path)
        yield f"{where}: removed", partial(_mutated, doc, path, None, True)
        current = _get(doc, path)
        for name, value in WRONG_VALUES:
            if _same_value(current, value):  # not a mutation (a zero already zero)
                continue
            yield f"{where}: {name}", partial(_mutated, doc, path, value, False)
    for path in [()] + [p for p in _paths(doc) if isinstance(_get(doc, p), dict)]:
        yield (f"{'.'.join(map(str, path)) or '(top)'}: extra field",
               partial(_mutated, doc, (*path, "unexpected_field"), 1, False))


def _same_value(current, value) -> bool:
    """Whether a YAML field holding ``current`` would be left as it is by ``value``."""
    numbers = (int, float)
    if type(current) in numbers and type(value) in numbers:
        return current == value
    return type(current) is type(value) and current == value


def _mutated(doc, path, value, delete: bool) -> bytes:
    return _dump(_set(doc, path, value, delete=delete))


def _get(doc, path):
    for key in path:
        doc = doc[key]
    return doc


def _dump(doc) -> bytes:
    return yaml.dump(doc, Dumper=_DUMPER, sort_keys=False, allow_unicode=True).encode()


_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
"""libyaml's emitter where PyYAML was built with it (ten times faster)."""


def table_mutations(text: str) -> Iterator[tuple[str, Callable[[], bytes]]]:
    """(label, a function making the bytes) of the line-level mutations of a text
    table."""
    lines = text.splitlines()
    step = max(1, len(lines) // 25)
    for i in range(0, len(lines), step):
        yield f"line {i + 1}: removed", _joined(lines[:i] + lines[i + 1:])
        yield f"line {i + 1}: doubled", _joined(lines[:i + 1] + lines[i:])
        tokens = lines[i].replace(",", " ").split()
        numbers = [t for t in tokens if _is_number(t)]
        if numbers:
            for bad in BAD_NUMBERS:
                if _is_number(bad) and _same_number(bad, numbers[-1]):
                    continue  # not a mutation (nan for nan, -1 for -1.0)
                changed = lines[i].replace(numbers[-1], bad, 1)
                yield (f"line {i + 1}: {numbers[-1]} -> {bad}",
                       _joined(lines[:i] + [changed] + lines[i + 1:]))


def _joined(lines: list[str]) -> Callable[[], bytes]:
    return partial(str.encode, "\n".join(lines))


def _same_number(a: str, b: str) -> bool:
    x, y = float(a), float(b)
    return x == y or (math.isnan(x) and math.isnan(y))


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def file_mutations(raw: bytes) -> Iterator[tuple[str, bytes]]:
    """(label, bytes) of the whole-file mutations (cheap: made at once)."""
    for fraction in (0.1, 0.33, 0.5, 0.77, 0.95):
        yield f"truncated at {fraction:.0%}", raw[:int(len(raw) * fraction)]
    yield "syntax: unclosed bracket", raw + b"\nbroken: [1, 2\n"
    yield "syntax: tab indentation", raw.replace(b"\n", b"\n\t", 3)
    yield "encoding: UTF-16", raw.decode("utf-8").encode("utf-16")
    yield "encoding: Latin-1 byte", raw + "\n# caf\u00e9\n".encode("latin-1")
    yield "empty", b""
    yield "binary noise", bytes(np.random.default_rng(0).integers(0, 256, 400,
                                                                  dtype=np.uint8))


# ------------------------------------------------------------------------- measuring

def classify(kind: FileKind, path: Path) -> tuple[str, str]:
    """(``clear`` | ``accepted`` | ``other``, the message, or for ``accepted`` the loaded
    object's :func:`fingerprint`) for one file."""
    try:
        loaded = kind.load(path)
    except (ValueError, OSError) as err:
        message = str(err)
        if path.name in message:
            return "clear", message
        return "other", f"{type(err).__name__} without the file name: {message}"
    except Exception as err:  # noqa: BLE001 - counting what escapes is the point
        return "other", f"{type(err).__name__}: {err}"
    return "accepted", fingerprint(loaded, path)


def fingerprint(obj, path: Path) -> str:
    """What a loader made of the file ``path``, as text that two loads share exactly when
    they are equal: dataclasses field by field, arrays by shape, dtype and bytes, the rest
    by ``repr``; the file's own path and name left out (the mutants and their reference
    are written under different names)."""
    def walk(value) -> str:
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            return type(value).__name__ + "(" + ",".join(
                f"{f.name}={walk(getattr(value, f.name))}"
                for f in dataclasses.fields(value)) + ")"
        if isinstance(value, np.ndarray):
            data = np.ascontiguousarray(value)
            return f"array{data.shape}{data.dtype}:{hashlib.sha1(data.tobytes()).hexdigest()}"
        if isinstance(value, (list, tuple)):
            return "[" + ",".join(walk(v) for v in value) + "]"
        if isinstance(value, dict):
            return "{" + ",".join(f"{k!r}:{walk(v)}" for k, v in value.items()) + "}"
        return repr(value)

    text = walk(obj).replace(str(path), "<file>")
    return re.sub(rf"{re.escape(path.stem)}\b", "<name>", text)


VALUE_CHANGES = {name for name, _ in WRONG_VALUES}
"""The YAML mutations that change a value (rather than remove or add a field)."""


def _changes_a_value(label: str) -> bool:
    """Whether the mutation ``label`` replaced a value: a YAML field's by one of
    :data:`WRONG_VALUES`, or a number in a table line."""
    last = label.rsplit(": ", 1)[-1]
    return last in VALUE_CHANGES or " -> " in last


def measure(*, limit_per_kind: int | None = None, progress: bool = True) -> dict:
    """Mutate every kind's valid files, load each mutant, and count the answers.

    Args:
        limit_per_kind: keep every k-th mutant so that at most this many are tried per
            kind (None: all).

    Returns:
        ``{"malformed_tried", "malformed_clear_error", "malformed_accepted",
        "malformed_other", "kinds": {kind: {...}}, "other_cases", "accepted_cases"}``.
    """
    from tqdm import tqdm

    with tempfile.TemporaryDirectory(prefix="cmanip-malformed-") as tmp:
        work = Path(tmp)
        kinds = file_kinds(work / "valid")
        per_kind = {}
        for kind in tqdm(kinds, desc="malformed inputs", unit="kind", disable=not progress):
            mutants = list(_mutants(kind))
            if limit_per_kind is not None and len(mutants) > limit_per_kind:
                mutants = mutants[::math.ceil(len(mutants) / limit_per_kind)]
            outcome = Outcome()
            folder = work / kind.name.replace(":", "_")
            folder.mkdir()
            references = {}
            for i, source in enumerate(kind.valid):
                path = folder / f"reference_{i}{kind.suffix}"
                path.write_bytes(Path(source).read_bytes())
                references[Path(source).name] = classify(kind, path)[1]
            for i, (label, make) in enumerate(mutants):
                path = folder / f"mutant_{i}{kind.suffix}"
                path.write_bytes(make())
                verdict, message = classify(kind, path)
                outcome.tried += 1
                if verdict == "clear":
                    outcome.clear += 1
                elif verdict == "accepted":
                    outcome.accepted.append(label)
                    if (_changes_a_value(label)
                            and message == references[label.split(": ", 1)[0]]):
                        outcome.ignored.append(label)
                else:
                    outcome.other.append(f"{label}: {message}"[:300])
            per_kind[kind.name] = outcome
    return {
        "malformed_tried": sum(o.tried for o in per_kind.values()),
        "malformed_clear_error": sum(o.clear for o in per_kind.values()),
        "malformed_accepted": sum(len(o.accepted) for o in per_kind.values()),
        "malformed_ignored": sum(len(o.ignored) for o in per_kind.values()),
        "malformed_other": sum(len(o.other) for o in per_kind.values()),
        "kinds": {k: {"tried": o.tried, "clear_error": o.clear,
                      "accepted": len(o.accepted), "ignored": len(o.ignored),
                      "other": len(o.other)}
                  for k, o in per_kind.items()},
        "other_cases": {k: o.other for k, o in per_kind.items() if o.other},
        "accepted_cases": {k: o.accepted for k, o in per_kind.items() if o.accepted},
        "ignored_cases": {k: o.ignored for k, o in per_kind.items() if o.ignored},
    }


def _mutants(kind: FileKind) -> Iterator[tuple[str, bytes]]:
    for source in kind.valid:
        raw = Path(source).read_bytes()
        name = Path(source).name
        text = raw.decode("utf-8")
        fields = yaml_mutations(text) if kind.structured else table_mutations(text)
        for label, make in fields:
            yield f"{name}: {label}", make
        for label, data in file_mutations(raw):
            yield f"{name}: {label}", partial(bytes, data)
