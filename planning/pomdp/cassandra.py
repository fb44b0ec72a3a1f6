"""Reading and writing Cassandra's ``.pomdp`` text format, so that models can be exchanged
with other solvers (SARSOP, APPL, pomdp-solve, POMDPs.jl).

Written files use only the plainest forms: the preamble, ``start:`` as a full vector, one
``T: a : s : s' p`` line per non-zero transition, one ``O: a : s' : o p`` line per non-zero
observation probability and ``R: a : s : * : * r`` per non-zero expected reward. Reading
accepts the format's common forms:

- preamble: ``discount``, ``values: reward|cost``, ``states|actions|observations`` as a
  count or a list of names, ``start:`` as a vector, ``uniform`` or one state name;
- ``T: a : s : s' p``, ``T: a : s`` + a row, ``T: a`` + a matrix or ``identity`` /
  ``uniform``; ``O`` likewise over (s', o); names, indices and ``*`` wildcards anywhere;
  later entries overwrite earlier ones;
- ``R: a : s : s' : o r``: an entry with ``*`` for both ``s'`` and ``o`` sets R(s, a); one
  naming ``s'`` or ``o`` contributes T(s, a, s') Z(a, s', o) r to it. (Mixing both kinds for
  the same (a, s) is not supported and is reported.)

Every error names the file, the line and what was expected.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp

from planning.pomdp.tabular import TabularPOMDP


class PomdpFormatError(ValueError):
    """A malformed ``.pomdp`` file: which file and line, and what was wrong."""

    def __init__(self, source: str, line: int, message: str):
        where = f"{source}:{line}" if line > 0 else source
        super().__init__(f"{where}: {message}")


def write_pomdp(pomdp: TabularPOMDP, path: str | Path) -> None:
    """Write ``pomdp`` to ``path`` in Cassandra's format (names kept, full precision)."""
    lines = [f"discount: {float(pomdp.discount)!r}", "values: reward",
             "states: " + " ".join(pomdp.states), "actions: " + " ".join(pomdp.actions),
             "observations: " + " ".join(pomdp.observations),
             "start: " + " ".join(repr(float(p)) for p in pomdp.initial), ""]
    for a, name in enumerate(pomdp.actions):
        t = pomdp.T[a].tocoo()
        for s, s2, p in zip(t.row, t.col, t.data, strict=True):
            if p != 0.0:
                lines.append(f"T: {name} : {pomdp.states[s]} : {pomdp.states[s2]} {float(p)!r}")
    for a, s2, o in zip(*np.nonzero(pomdp.Z), strict=True):
        lines.append(f"O: {pomdp.actions[a]} : {pomdp.states[s2]} : {pomdp.observations[o]} "
                     f"{float(pomdp.Z[a, s2, o])!r}")
    for s, a in zip(*np.nonzero(pomdp.R), strict=True):
        lines.append(f"R: {pomdp.actions[a]} : {pomdp.states[s]} : * : * "
                     f"{float(pomdp.R[s, a])!r}")
    Path(path).write_text("\n".join(lines) + "\n")


def read_pomdp(path: str | Path) -> TabularPOMDP:
    """Read a ``.pomdp`` file; raises :class:`PomdpFormatError` on malformed input."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise PomdpFormatError(str(path), 0, f"cannot read: {err}") from err
    except UnicodeDecodeError as err:
        raise PomdpFormatError(str(path), 0, f"not UTF-8 text (byte {err.start}: "
                                             f"{err.reason})") from None
    return _Parser(str(path), text).parse()


class _Parser:
    """A line-oriented reader: entries start with a keyword and a colon; the numbers of
    row/matrix forms continue on the following lines."""

    def __init__(self, source: str, text: str):
        self.source = source
        self.tokens: list[tuple[int, str]] = []
        for number, raw in enumerate(text.splitlines(), start=1):
            line = raw.split("#", 1)[0].replace(":", " : ")
            self.tokens += [(number, tok) for tok in line.split()]
        self.pos = 0

    def error(self, message: str, line: int | None = None) -> PomdpFormatError:
        if line is None:
            line = self.tokens[min(self.pos, len(self.tokens) - 1)][0] if self.tokens else 0
        return PomdpFormatError(self.source, line, message)

    # -- token helpers
    def peek(self) -> str | None:
        return self.tokens[self.pos][1] if self.pos < len(self.tokens) else None

    def take(self) -> tuple[int, str]:
        if self.pos >= len(self.tokens):
            raise self.error("unexpected end of file")
        self.pos += 1
        return self.tokens[self.pos - 1]

    def expect(self, token: str) -> None:
        line, got = self.take()
        if got != token:
            raise self.error(f"expected '{token}', got '{got}'", line)

    def number(self) -> float:
        line, tok = self.take()
        try:
            value = float(tok)
        except ValueError:
            raise self.error(f"expected a number, got '{tok}'", line) from None
        if not np.isfinite(value):
            raise self.error(f"expected a finite number, got '{tok}'", line)
        return value

    def numbers(self, count: int) -> np.ndarray:
        return np.array([self.number() for _ in range(count)])

    def at_keyword(self) -> bool:
        tok = self.peek()
        return tok is None or (tok in KEYWORDS and self.pos + 1 < len(self.tokens)
                               and self.tokens[self.pos + 1][1] == ":")

    def names(self, kind: str) -> tuple[str, ...]:
        self.expect(":")
        line, first = self.take()
        if first.isdigit() and self.at_keyword():
            return tuple(str(i) for i in range(int(first)))
        out = [first]
        while not self.at_keyword():
            out.append(self.take()[1])
        if len(set(out)) != len(out):
            raise self.error(f"repeated {kind} name", line)
        return tuple(out)

    def index(self, token: str, names: tuple[str, ...], kind: str, line: int) -> list[int]:
        if token == "*":
            return list(range(len(names)))
        if token in self.lookup[kind]:
            return [self.lookup[kind][token]]
        if token.isdigit() and int(token) < len(names):
            return [int(token)]
        raise self.error(f"unknown {kind} '{token}' (expected one of {len(names)} "
                         f"{kind}s, an index or *)", line)

    # -- the file
    def parse(self) -> TabularPOMDP:
        discount, sign = None, 1.0
        states = actions = observations = None
        start_tokens: list[tuple[int, str]] | None = None
        while self.peek() in ("discount", "values", "states", "actions", "observations",
                              "start"):
            line, key = self.take()
            if key == "discount":
                self.expect(":")
                discount = self.number()
            elif key == "values":
                self.expect(":")
                vline, kind = self.take()
                if kind not in ("reward", "cost"):
                    raise self.error(f"values must be reward or cost, got '{kind}'", vline)
                sign = 1.0 if kind == "reward" else -1.0
            elif key == "start":
                if self.peek() != ":":
                    raise self.error("only 'start:' is supported (not include/exclude)",
                                     line)
                self.expect(":")
                start_tokens = []
                while not self.at_keyword():
                    start_tokens.append(self.take())
            else:
                value = self.names(key[:-1])
                states = value if key == "states" else states
                actions = value if key == "actions" else actions
                observations = value if key == "observations" else observations
        missing = [k for k, v in (("discount", discount), ("states", states),
                                  ("actions", actions), ("observations", observations))
                   if v is None]
        if missing:
            raise self.error(f"missing preamble entries: {', '.join(missing)}")
        self.lookup = {"state": {n: i for i, n in enumerate(states)},
                       "action": {n: i for i, n in enumerate(actions)},
                       "observation": {n: i for i, n in enumerate(observations)}}
        S, A, n_obs = len(states), len(actions), len(observations)
        T = [sp.lil_matrix((S, S)) for _ in range(A)]
        Z = np.zeros((A, S, n_obs))
        R_base = np.zeros((S, A))
        base_set = np.zeros((S, A), dtype=bool)
        R_specific: list[tuple[list[int], list[int], list[int], list[int], float]] = []
        while self.peek() is not None:
            line, key = self.take()
            if key == "T":
                self._matrix_entry(line, T, (actions, states, states),
                                   ("action", "state", "state"), lil=True)
            elif key == "O":
                self._matrix_entry(line, Z, (actions, states, observations),
                                   ("action", "state", "observation"), lil=False)
            elif key == "R":
                self.expect(":")
                fields = self._fields(4, line)
                if len(fields) != 4:
                    raise self.error("R entries need 'R: a : s : s' : o value'", line)
                value = sign * self.number()
                a = self.index(fields[0][1], actions, "action", fields[0][0])
                s = self.index(fields[1][1], states, "state", fields[1][0])
                if fields[2][1] == "*" and fields[3][1] == "*":
                    for ai in a:
                        R_base[s, ai] = value
                        base_set[s, ai] = True
                else:
                    s2 = self.index(fields[2][1], states, "state", fields[2][0])
                    o = self.index(fields[3][1], observations, "observation", fields[3][0])
                    R_specific.append((a, s, s2, o, value))
            else:
                raise self.error(f"expected T:, O: or R:, got '{key}'", line)
        T = tuple(t.tocsr() for t in T)
        R = R_base.copy()
        for a, s, s2, o, value in R_specific:
            for ai in a:
                if base_set[s, ai].any():
                    raise self.error(f"R for action {actions[ai]} mixes '* : *' entries with "
                                     "entries naming s' or o", 0)
                weights = T[ai][s][:, s2].toarray() * Z[ai][np.ix_(s2, o)].sum(axis=1)
                R[s, ai] += value * weights.sum(axis=1)
        initial = self._start(start_tokens, states)
        try:
            return TabularPOMDP(states, actions, observations, T, Z, R, discount, initial)
        except ValueError as err:
            raise PomdpFormatError(self.source, 0, str(err)) from None

    def _fields(self, most: int, line: int) -> list[tuple[int, str]]:
        """Up to ``most`` colon-separated index fields, stopping before a number."""
        fields = [self.take()]
        while len(fields) < most and self.peek() == ":":
            self.take()
            fields.append(self.take())
        return fields

    def _matrix_entry(self, line, target, names, kinds, *, lil: bool) -> None:
        self.expect(":")
        fields = self._fields(3, line)
        index = [self.index(tok, names[i], kinds[i], ln) for i, (ln, tok) in enumerate(fields)]
        n_rows, n_cols = len(names[1]), len(names[2])
        if len(fields) == 3:
            value = self.number()
            for a in index[0]:
                for r in index[1]:
                    for c in index[2]:
                        target[a][r, c] = value
            return
        if len(fields) == 2:
            row = self._row(n_cols)
            for a in index[0]:
                for r in index[1]:
                    target[a][r, :] = row
            return
        keyword = self.peek()
        if keyword in ("identity", "uniform"):
            self.take()
            if keyword == "identity" and n_rows != n_cols:
                raise self.error("'identity' needs a square matrix", line)
            block = (np.eye(n_rows) if keyword == "identity"
                     else np.full((n_rows, n_cols), 1.0 / n_cols))
        else:
            block = self.numbers(n_rows * n_cols).reshape(n_rows, n_cols)
        for a in index[0]:
            if lil:
                target[a] = sp.lil_matrix(block)
            else:
                target[a] = block

    def _row(self, n: int) -> np.ndarray:
        if self.peek() == "uniform":
            self.take()
            return np.full(n, 1.0 / n)
        return self.numbers(n)

    def _start(self, tokens, states) -> np.ndarray:
        S = len(states)
        if not tokens or (len(tokens) == 1 and tokens[0][1] == "uniform"):
            return np.full(S, 1.0 / S)
        if len(tokens) == 1 and tokens[0][1] in self.lookup["state"]:
            out = np.zeros(S)
            out[self.lookup["state"][tokens[0][1]]] = 1.0
            return out
        if len(tokens) != S:
            raise self.error(f"start: expected {S} probabilities, 'uniform' or a state name",
                             tokens[0][0])
        try:
            start = np.array([float(tok) for _, tok in tokens])
        except ValueError:
            raise self.error("start: expected numbers", tokens[0][0]) from None
        if not np.isfinite(start).all():
            raise self.error("start: expected finite numbers", tokens[0][0])
        return start


KEYWORDS = ("discount", "values", "states", "actions", "observations", "start", "T", "O", "R")
