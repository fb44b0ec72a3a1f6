"""One trial runner for every study: serial, a local process pool, or Ray; results that
outlive a killed run (DESIGN.md's trial-runner seam).

A study hands :func:`map_trials` a top-level function and its jobs. A :class:`Job` is a
key (unique within the study, e.g. ``"3dof/17"``) and the function's arguments: frozen
settings and seeds, so a trial's result depends on nothing else: not on the backend, the
worker count or the order in which trials finish. Workers build their heavy objects
(plants, manifolds, solved policies) from those settings through the studies' per-process
caches; a Drake plant is never pickled.

With a :class:`TrialStore` every finished trial is appended to ``DIR/trials.jsonl`` as one
line, and a resumed run (``--resume``) runs only the trials whose keys are missing. Every
result, fresh or stored, goes through the same JSON encoding (:func:`encode`), so a study
killed part-way and resumed summarises exactly the values an uninterrupted run does
(only the wall times a study measures differ, as they do between any two runs).

Why Ray: it runs the same tasks on one machine or a cluster (``--address HOST:PORT`` or
``auto``) with no code of ours for scheduling, transport or worker restarts. It is
imported here only, and only when asked for: the local default is a process pool, which
needs no service. Ray is started bound to localhost, without its dashboard or usage
reporting.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import multiprocessing
import os
import signal
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

BACKENDS = ("serial", "processes", "ray")

TRIALS_FILE = "trials.jsonl"

_PACKAGES = ("models", "estimation", "planning", "diagrams", "experiments")
"""Dataclasses from these packages only are rebuilt from a trials file."""


@dataclass(frozen=True)
class Backend:
    """Where trials run.

    Attributes:
        kind: ``serial`` (this process), ``processes`` (a spawned pool on this machine)
            or ``ray`` (a local Ray instance, or the cluster at ``address``).
        workers: processes (``processes``) or CPUs Ray may use locally (``ray``).
        address: a Ray cluster's ``HOST:PORT`` or ``auto``; None starts a local Ray.
    """

    kind: str = "processes"
    workers: int = 1
    address: str | None = None

    def __post_init__(self):
        if self.kind not in BACKENDS:
            raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got "
                             f"{self.kind!r}")
        if self.workers < 1:
            raise ValueError(f"workers must be >= 1, got {self.workers}")
        if self.address is not None and self.kind != "ray":
            raise ValueError("--address is for the ray backend")


@dataclass(frozen=True)
class Job:
    """One trial: ``fn(*args)``, stored under ``key``."""

    key: str
    args: tuple


class TrialsInterrupted(Exception):
    """Ctrl-C during a study: the workers are stopped and the finished trials kept."""

    def __init__(self, done: int, total: int, store: Path | None):
        self.done, self.total, self.store = done, total, store
        kept = (f"kept in {store}; run the same command with --resume to finish"
                if store is not None else "not kept (no output directory)")
        super().__init__(f"interrupted: {done} of {total} trials finished, {kept}")


# ------------------------------------------------------------------------ the encoding

def encode(value: Any) -> Any:
    """A JSON-ready form of a trial's result: numpy arrays with their dtype and shape,
    dataclasses with their class, tuples marked as tuples; floats exact (``repr``
    round-trips)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        cls = type(value)
        return {"__dataclass__": f"{cls.__module__}.{cls.__qualname__}",
                "fields": {f.name: encode(getattr(value, f.name))
                           for f in dataclasses.fields(value)}}
    if isinstance(value, np.ndarray):
        return {"__ndarray__": value.tolist(), "dtype": value.dtype.str,
                "shape": list(value.shape)}
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple):
        return {"__tuple__": [encode(v) for v in value]}
    if isinstance(value, list):
        return [encode(v) for v in value]
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise TypeError("a trial result's dict keys must be strings")
        return {k: encode(v) for k, v in value.items()}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"cannot store a {type(value).__name__} in a trials file")


def decode(value: Any) -> Any:
    """The inverse of :func:`encode`."""
    if isinstance(value, list):
        return [decode(v) for v in value]
    if not isinstance(value, dict):
        return value
    if "__ndarray__" in value:
        return np.array(value["__ndarray__"], dtype=np.dtype(value["dtype"])).reshape(
            value["shape"])
    if "__tuple__" in value:
        return tuple(decode(v) for v in value["__tuple__"])
    if "__dataclass__" in value:
        module, _, name = value["__dataclass__"].rpartition(".")
        if module.split(".")[0] not in _PACKAGES:
            raise ValueError(f"a trials file may only name this project's classes, got "
                             f"{value['__dataclass__']!r}")
        cls = getattr(importlib.import_module(module), name)
        return cls(**{k: decode(v) for k, v in value["fields"].items()})
    return {k: decode(v) for k, v in value.items()}


# ------------------------------------------------------------------------- the store

class TrialStore:
    """``DIR/trials.jsonl``: a header line with the study's name and settings, then one line
    per finished trial, ``{"key": ..., "result": ...}``.

    Each line is written whole with one ``write`` on a file opened for appending and
    flushed to disk before the trial counts as done; a line cut short by a kill (no
    newline, or not JSON) is dropped when the file is read, and truncated before new lines
    are appended.

    Args:
        directory: the study's output directory.
        study: the study's name (``configest``, ``mpf/compare``...).
        settings: the JSON-ready settings the results depend on.
        resume: keep the trials already in the file (they must come from the same study
            and settings); otherwise the file starts empty.

    Raises:
        ValueError: ``resume`` onto a file of another study or other settings, or a file
            that is not a trials file.
    """

    def __init__(self, directory: Path, study: str, settings: dict, *, resume: bool):
        self.path = Path(directory) / TRIALS_FILE
        self.header = {"study": study, "settings": json.loads(json.dumps(settings))}
        self.done: dict[str, Any] = {}
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if resume and self.path.exists():
            good = self._read()
            with open(self.path, "r+b") as f:  # drop a line cut short by a kill
                f.truncate(good)
        else:
            self.path.write_text(json.dumps(self.header) + "\n")

    def _read(self) -> int:
        """Load the stored trials; return the byte length of the complete lines."""
        raw = self.path.read_bytes()
        lines = raw.split(b"\n")
        complete = lines[:-1]  # the piece after the last newline is unfinished
        if not complete:
            raise ValueError(f"{self.path}: not a trials file (no header line)")
        try:
            header = json.loads(complete[0])
        except ValueError as err:
            raise ValueError(f"{self.path}: line 1: not a trials header ({err})") from None
        if not isinstance(header, dict) or header.get("study") != self.header["study"]:
            raise ValueError(f"{self.path}: written by study {header.get('study')!r}, not "
                             f"{self.header['study']!r}; use another --out or drop --resume")
        if header.get("settings") != self.header["settings"]:
            fields = _differing(header.get("settings") or {}, self.header["settings"])
            raise ValueError(f"{self.path}: written with other settings ({fields}); use "
                             f"another --out, or drop --resume to start over")
        length = len(complete[0]) + 1
        for number, line in enumerate(complete[1:], start=2):
            try:
                entry = json.loads(line)
                self.done[entry["key"]] = entry["result"]
            except (ValueError, KeyError, TypeError):
                if number == len(complete):  # the last line, cut short mid-write
                    break
                raise ValueError(f"{self.path}: line {number} is not a trial record") from None
            length += len(line) + 1
        return length

    def append(self, key: str, encoded: Any) -> None:
        """Store one finished trial (already :func:`encode` d)."""
        line = (json.dumps({"key": key, "result": encoded}) + "\n").encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            os.write(fd, line)
            os.fsync(fd)
        finally:
            os.close(fd)
        self.done[key] = encoded


def _differing(stored: dict, now: dict) -> str:
    keys = sorted(k for k in set(stored) | set(now) if stored.get(k) != now.get(k))
    return ", ".join(f"{k}: stored {stored.get(k)!r}, now {now.get(k)!r}" for k in keys)


# ------------------------------------------------------------------------ the runner

def _call_job(payload: tuple[Callable, Job]) -> tuple[str, Any]:
    """Run one trial in a worker; its key and its encoded result."""
    fn, job = payload
    return job.key, encode(fn(*job.args))


def map_trials(fn: Callable, jobs: Sequence[Job], *, backend: Backend,
               store: TrialStore | None = None, desc: str = "trials",
               progress: bool = True) -> list:
    """``fn(*job.args)`` for every job, in job order, on ``backend``.

    Args:
        fn: a module-level function (workers import it by name).
        jobs: the trials; keys unique.
        backend: where they run.
        store: where finished trials go (and which are already done).
        desc: the progress bar's label.
        progress: show one bar (trials done, rate, ETA) whatever the backend.

    Returns:
        The decoded results in job order: fresh ones round-tripped through the encoding,
        like stored ones, so a resumed study sees exactly the values a whole one does.

    Raises:
        TrialsInterrupted: on Ctrl-C, after stopping the workers (finished trials kept).
    """
    keys = [job.key for job in jobs]
    wanted = set(keys)
    if len(wanted) != len(keys):
        raise ValueError("trial keys must be unique")
    done = {} if store is None else {k: v for k, v in store.done.items() if k in wanted}
    pending = [job for job in jobs if job.key not in done]
    bar = tqdm(total=len(jobs), initial=len(done), desc=desc, unit="trial",
               disable=not progress, smoothing=0.1)

    def finished(key: str, encoded: Any) -> None:
        if store is not None:
            store.append(key, encoded)
        done[key] = encoded
        bar.update()

    run = {"serial": _run_serial, "processes": _run_processes, "ray": _run_ray}[backend.kind]
    try:
        if pending:
            run(fn, pending, backend, finished)
    except KeyboardInterrupt:
        raise TrialsInterrupted(len(done), len(jobs),
                                None if store is None else store.path) from None
    finally:
        bar.close()
    return [decode(done[key]) for key in keys]


def _run_serial(fn, jobs, backend, finished) -> None:
    for job in jobs:
        finished(*_call_job((fn, job)))


def _run_processes(fn, jobs, backend, finished) -> None:
    if backend.workers == 1:
        _run_serial(fn, jobs, backend, finished)
        return
    context = multiprocessing.get_context("spawn")
    pool = context.Pool(min(backend.workers, len(jobs)), initializer=_ignore_interrupts)
    try:
        for key, encoded in pool.imap_unordered(_call_job, [(fn, j) for j in jobs]):
            finished(key, encoded)
        pool.close()
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()


def _ignore_interrupts() -> None:
    """In a pool worker: Ctrl-C reaches the whole process group, but only the parent
    handles it (it stops the pool), so workers print no tracebacks of their own."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


LOCAL_RAY_ATTEMPTS = 3
"""Starts of a local Ray node tried before giving up: Ray waits a fixed 30 s for its raylet
to register, which a loaded 2-core machine can miss (seen in the test suite with another
study running); a second start then succeeds."""


def _start_local_ray(ray, workers: int) -> None:
    """A local Ray node on the loopback interface with ``workers`` CPUs, retried when it
    times out starting (see :data:`LOCAL_RAY_ATTEMPTS`)."""
    for attempt in range(1, LOCAL_RAY_ATTEMPTS + 1):
        try:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                     _node_ip_address="127.0.0.1", object_store_memory=100 * 2**20,
                     configure_logging=False)
            return
        except Exception as err:  # Ray raises a bare Exception for this timeout
            if "timed out during startup" not in str(err) or attempt == LOCAL_RAY_ATTEMPTS:
                raise
            ray.shutdown()


def _run_ray(fn, jobs, backend, finished) -> None:
    import ray  # the only import of Ray in the project

    started = not ray.is_initialized()
    if started:
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        if backend.address is None:
            _start_local_ray(ray, backend.workers)
        else:
            ray.init(address=backend.address, log_to_driver=False,
                     configure_logging=False)
    task = ray.remote(num_cpus=1, max_retries=2)(_call_job)
    waiting = []
    try:
        waiting = [task.remote((fn, job)) for job in jobs]
        while waiting:
            ready, waiting = ray.wait(waiting, num_returns=1)
            finished(*ray.get(ready[0]))
    except BaseException:
        for ref in waiting:
            ray.cancel(ref, force=True)
        raise
    finally:
        if started:
            ray.shutdown()
