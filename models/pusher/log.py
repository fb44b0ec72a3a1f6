"""The pusher-slider log: what the rig's sensors recorded, one row per force-sensor sample.

The file is plain CSV so that data from a real robot can be fed through the same
estimator. Layout::

    # contact-manipulation pusher log v1
    # object: rect1            (a built-in object name or a path to an object file)
    # rod_radius_m: 0.003125
    # contact_threshold_n: 0.3
    # surface: plywood         (free text; for reports)
    t_s,rod0_x_m,rod0_y_m,rod0_fx_n,rod0_fy_n,rod1_x_m,...,vision_ok,vision_x_m,...
    0.004,...

Columns (SI units; world frame; one row per force sample):

- ``t_s``: time (s), increasing.
- ``rodK_x_m, rodK_y_m`` (K = 0, 1): the rod's centre, from the robot's kinematics.
- ``rodK_fx_n, rodK_fy_n``: the force the rod applies *to the object* (N); contact is
  ``|f| >= contact_threshold_n`` (seed 003 sec. III).
- ``vision_ok``: 1 on the rows where a new camera pose arrived, else 0.
- ``vision_x_m, vision_y_m, vision_theta_rad``: that pose (ignored when ``vision_ok`` = 0).
- ``truth_x_m, truth_y_m, truth_theta_rad``: ground truth if known, else ``nan``.
- ``carriage_x_m, carriage_y_m, carriage_yaw_rad``: the carriage's pose (for drawing; may
  be ``nan``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

MAGIC = "contact-manipulation pusher log v1"
COLUMNS = (
    ["t_s"]
    + [f"rod{k}_{q}" for k in (0, 1) for q in ("x_m", "y_m", "fx_n", "fy_n")]
    + ["vision_ok", "vision_x_m", "vision_y_m", "vision_theta_rad",
       "truth_x_m", "truth_y_m", "truth_theta_rad",
       "carriage_x_m", "carriage_y_m", "carriage_yaw_rad"]
)
META_FIELDS = ("object", "rod_radius_m", "contact_threshold_n", "surface")


class LogFormatError(ValueError):
    """A log file is malformed; the message names the file, and the line or column."""


@dataclass(frozen=True)
class PushLog:
    """A recorded push, as arrays (N rows).

    Attributes:
        t: (N,) s. rods: (N, 2, 2) rod centres (m). forces: (N, 2, 2) forces on the object
        (N). vision_ok: (N,) bool. vision: (N, 3) camera poses (m, rad). truth: (N, 3) or
        nan. carriage: (N, 3) or nan.
        object_name: built-in object name or path. rod_radius_m, contact_threshold_n:
        sensing constants. surface: a label.
    """

    t: np.ndarray
    rods: np.ndarray
    forces: np.ndarray
    vision_ok: np.ndarray
    vision: np.ndarray
    truth: np.ndarray
    carriage: np.ndarray
    object_name: str
    rod_radius_m: float
    contact_threshold_n: float
    surface: str = ""
    extra: dict[str, str] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.t)

    def head(self, n: int) -> PushLog:
        """The first ``n`` rows."""
        return replace(self, **{f.name: getattr(self, f.name)[:n] for f in fields(self)
                                if isinstance(getattr(self, f.name), np.ndarray)})

    def contacts(self) -> np.ndarray:
        """(N, 2) bool: each rod's force at or above the contact threshold."""
        return np.linalg.norm(self.forces, axis=2) >= self.contact_threshold_n

    def write(self, path: str | Path) -> None:
        data = np.column_stack([
            self.t,
            np.concatenate([self.rods[:, 0], self.forces[:, 0],
                            self.rods[:, 1], self.forces[:, 1]], axis=1),
            self.vision_ok.astype(float), self.vision, self.truth, self.carriage])
        header = [f"# {MAGIC}", f"# object: {self.object_name}",
                  f"# rod_radius_m: {self.rod_radius_m!r}",
                  f"# contact_threshold_n: {self.contact_threshold_n!r}",
                  f"# surface: {self.surface}"]
        header += [f"# {k}: {v}" for k, v in self.extra.items()]
        with open(path, "w") as f:
            f.write("\n".join(header) + "\n" + ",".join(COLUMNS) + "\n")
            np.savetxt(f, data, delimiter=",", fmt="%.9g")

    @staticmethod
    def read(path: str | Path) -> PushLog:
        """Read a log, checking the header, the columns and the values.

        Raises:
            LogFormatError: naming the file and the line or column at fault.
        """
        path = Path(path)
        if not path.is_file():
            raise LogFormatError(f"{path}: no such log file")
        raw = path.read_bytes()
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as err:
            line = raw.count(b"\n", 0, err.start) + 1
            raise LogFormatError(f"{path}:{line}: not UTF-8 text (byte 0x{raw[err.start]:02x} "
                                 "cannot be decoded)") from err
        lines = text.splitlines()
        if not lines or lines[0].strip() != f"# {MAGIC}":
            raise LogFormatError(f"{path}:1: expected the first line '# {MAGIC}'")
        meta: dict[str, str] = {}
        row = 1
        while row < len(lines) and lines[row].startswith("#"):
            key, sep, value = lines[row][1:].partition(":")
            if not sep:
                raise LogFormatError(f"{path}:{row + 1}: expected '# key: value'")
            meta[key.strip()] = value.strip()
            row += 1
        for key in META_FIELDS[:3]:
            if key not in meta:
                raise LogFormatError(f"{path}: header field '{key}' is missing")
        if row >= len(lines):
            raise LogFormatError(f"{path}: the column header line is missing")
        names = [n.strip() for n in lines[row].split(",")]
        missing = [c for c in COLUMNS if c not in names]
        if missing:
            raise LogFormatError(f"{path}:{row + 1}: missing column(s) {', '.join(missing)}")
        try:
            table = np.loadtxt(lines[row + 1:], delimiter=",", ndmin=2)
        except ValueError as err:
            raise LogFormatError(_bad_row(path, lines, row + 1, names)
                                 or f"{path}: the data rows cannot be read") from err
        if table.shape[0] == 0:
            raise LogFormatError(f"{path}: no data rows")
        if table.shape[1] != len(names):
            raise LogFormatError(_bad_row(path, lines, row + 1, names)
                                 or f"{path}: rows have {table.shape[1]} values for "
                                    f"{len(names)} columns")
        col = {n: table[:, i] for i, n in enumerate(names)}
        # The file's line number (1-based, as an editor shows it) of each data row:
        # np.loadtxt skipped blank and comment-only lines.
        line_of_row = [i + 1 for i in range(row + 1, len(lines))
                       if lines[i].split("#", 1)[0].strip()]
        t = col["t_s"]
        if np.any(np.diff(t) <= 0):
            bad = line_of_row[int(np.argmax(np.diff(t) <= 0)) + 1]
            raise LogFormatError(f"{path}:{bad}: column t_s must increase")
        for name in COLUMNS[:10]:
            if not np.all(np.isfinite(col[name])):
                bad = line_of_row[int(np.argmax(~np.isfinite(col[name])))]
                raise LogFormatError(f"{path}:{bad}: column {name} must be finite")
        try:
            radius = float(meta["rod_radius_m"])
            threshold = float(meta["contact_threshold_n"])
        except ValueError as err:
            raise LogFormatError(f"{path}: rod_radius_m and contact_threshold_n must be "
                                 f"numbers ({err})") from err
        for key, value in (("rod_radius_m", radius), ("contact_threshold_n", threshold)):
            if not (np.isfinite(value) and value > 0):
                raise LogFormatError(f"{path}: header field '{key}' must be a positive "
                                     f"finite number, got {meta[key]!r}")

        def stack(*names):
            return np.column_stack([col[n] for n in names])

        rods = np.stack([stack(f"rod{k}_x_m", f"rod{k}_y_m") for k in (0, 1)], axis=1)
        forces = np.stack([stack(f"rod{k}_fx_n", f"rod{k}_fy_n") for k in (0, 1)], axis=1)
        extra = {k: v for k, v in meta.items() if k not in META_FIELDS}
        return PushLog(t, rods, forces, col["vision_ok"] > 0.5,
                       stack("vision_x_m", "vision_y_m", "vision_theta_rad"),
                       stack("truth_x_m", "truth_y_m", "truth_theta_rad"),
                       stack("carriage_x_m", "carriage_y_m", "carriage_yaw_rad"),
                       meta["object"], radius, threshold, meta.get("surface", ""), extra)


def _bad_row(path: Path, lines: list[str], first: int, names: list[str]) -> str:
    """The first malformed data row of ``lines[first:]``, as ``'<file>:<line>: why'``.

    Lines are numbered as an editor shows them: 1-based, counting every line of the file
    (the magic line is line 1). Blank lines and ``#`` comments are skipped, as
    ``np.loadtxt`` skips them, and values are parsed by ``np.loadtxt`` itself. Returns ''
    when every row has ``len(names)`` numbers.
    """
    for index in range(first, len(lines)):
        data = lines[index].split("#", 1)[0].strip()
        if not data:
            continue
        values = data.split(",")
        where = f"{path}:{index + 1}"
        if len(values) != len(names):
            return f"{where}: {len(values)} values for the {len(names)} columns of the header"
        for name, value in zip(names, values, strict=True):
            if not _is_number(value):
                return f"{where}: column {name}: {value.strip()!r} is not a number"
    return ""


def _is_number(text: str) -> bool:
    """Does ``np.loadtxt`` read ``text`` (one comma-free field) as a number?"""
    if not text.strip():
        return False
    try:
        return np.loadtxt([text], delimiter=",", ndmin=1).size == 1
    except ValueError:
        return False
