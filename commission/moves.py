"""The machine's own moves (``spec.toml`` ``[trajectory]`` ``file`` or ``[[trajectory.move]]``).

A user profile is what the machine's trajectory generator commands, given either

* as a CSV file (``trajectory.file``, the path relative to the spec file): a header row
  naming the columns ``t`` (s) and ``q`` (m), optionally ``v`` (m/s) and ``a`` (m/s^2),
  one sample per row, ``t`` strictly increasing (any start; not necessarily uniform).
  Missing ``v``/``a`` are the central differences of ``q``/``v`` (``numpy.gradient``); the
  profile is resampled to the controller's rate by linear interpolation
  (:func:`commission.controllers.trajectory.resampled`), positions relative to the first
  row's (the simulation starts there, at rest);
* or as point-to-point moves (``[[trajectory.move]]`` tables, in order): ``to`` (m, the
  target position; the first move starts at 0), ``v_max`` (m/s), ``a_max`` (m/s^2),
  optional ``j_max`` (m/s^3; absent: unlimited jerk, a trapezoidal velocity; give it to
  every move or to none) and optional ``dwell`` (s, the rest at the target, default 0).
  Each move is the time-optimal S-curve under its limits
  (:func:`commission.controllers.trajectory.scurve_segments`), rendered exactly at the
  controller's samples (no filter: the drive follows its generator's q, v, a).

Either way the profile starts and ends at rest, and validate's run holds the end position
for :data:`commission.scenarios.CASE2_TAIL` s more, so that e_F measures the standstill.
Its envelope (peak |v|, peak |a|, span max q - min q) is the spec's envelope
(``trajectory.v_max``, ``a_max``, ``travel``) unless those keys are given (then they must
cover it): see :mod:`commission.spec`.

A profile is hashable by its content (sha256), so that scenarios carrying it are
compared and cached like the paper's Case 1 and Case 2.
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
import os
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from commission.controllers import trajectory as _traj
from commission.errors import SpecError
from commission.units import unit

#: Largest profile file read, bytes.
MAX_PROFILE_BYTES = 256 * 1024**2
#: Most rows of a profile file (several times the sample cap, for files sampled faster than the controller).
MAX_PROFILE_ROWS = 2_000_000
#: Most ``[[trajectory.move]]`` tables.
MAX_MOVES = 1000
#: A profile file must start and end at rest: |v| at its first and last row at most this fraction of its peak.
REST_FRACTION = 0.01
#: Columns of a profile file: required, then optional.
FILE_COLUMNS = ("t", "q", "v", "a")

#: Keys of one ``[[trajectory.move]]`` table: (required, unit, lowest, highest), both ends inclusive.
MOVE_KEYS: dict[str, tuple[bool, str, float, float]] = {
    "to": (True, "m", -100.0, 100.0),
    "v_max": (True, "m/s", 1e-6, 100.0),
    "a_max": (True, "m/s^2", 1e-6, 1e5),
    "j_max": (False, "m/s^3", 1e-6, 1e9),
    "dwell": (False, "s", 0.0, 60.0),
}


@dataclass(frozen=True, eq=False)
class UserProfile:
    """The machine's moves, parsed and checked (module docstring).

    Equality and hashing go by ``(kind, sha256)``, not by the arrays, so that scenarios that
    carry the same profile compare and cache as one.

    Attributes
    ----------
    kind : str
        ``"file"`` or ``"moves"``.
    label : str
        What messages call it: ``trajectory.file = 'moves.csv'`` or ``trajectory.move (4 moves)``.
    path : str or None
        Absolute path of the file (``kind == "file"``).
    sha256 : str
        Of the file's bytes, or of the moves' canonical text.
    moves : tuple of Move
        ``kind == "moves"``.
    t, q, v, a : ndarray or None
        ``kind == "file"``: the rows, t shifted to start at 0 (s, m, m/s, m/s^2).
    end : float
        Time at which the profile is at rest for good, s.
    v_peak, a_peak : float
        Largest |v| (m/s) and |a| (m/s^2) of the profile.
    span : float
        max q - min q, m.
    """

    kind: str
    label: str
    path: str | None
    sha256: str
    end: float
    v_peak: float
    a_peak: float
    span: float
    moves: tuple[_traj.Move, ...] = ()
    t: np.ndarray | None = field(default=None, repr=False)
    q: np.ndarray | None = field(default=None, repr=False)
    v: np.ndarray | None = field(default=None, repr=False)
    a: np.ndarray | None = field(default=None, repr=False)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, UserProfile) and (self.kind, self.sha256) == (other.kind, other.sha256)

    def __hash__(self) -> int:
        return hash((self.kind, self.sha256))

    def __deepcopy__(self, memo: dict) -> "UserProfile":
        return self  # immutable (arrays read-only)

    def render(self, duration: float, Ts: float, y0: float = 0.0) -> _traj.Trajectory:
        """q_d, dq_d, ddq_d every ``Ts`` s over ``duration`` s, starting at ``y0`` (m), at rest after :attr:`end`."""
        if self.kind == "moves":
            sched, _ = _traj.scurve_schedule(self.moves)
            return _traj.scheduled(sched, duration, Ts, start=y0)
        return _traj.resampled(self.t, self.q, self.v, self.a, duration, Ts, start=y0)  # type: ignore[arg-type]

    def drive_demand(self, mass: float, viscous: float, Ts: float) -> tuple[float, float, float]:
        """Largest ``mass |a| + viscous |v|`` along the profile sampled every ``Ts`` s, u-unit.

        Returns
        -------
        need, v, a : float
            The largest value and the speed (m/s) and acceleration (m/s^2) where it occurs.
        """
        tr = self.render(self.end + 2 * Ts, Ts)
        f = mass * np.abs(tr.ddqd) + viscous * np.abs(tr.dqd)
        k = int(np.argmax(f))
        return float(f[k]), float(abs(tr.dqd[k])), float(abs(tr.ddqd[k]))

    def to_spec(self) -> dict[str, Any]:
        """The ``[trajectory]`` keys that re-create this profile (tuning.json's spec)."""
        if self.kind == "file":
            return {"file": self.path, "file_sha256": self.sha256}
        out = []
        for m in self.moves:
            d: dict[str, Any] = {"to": m.to, "v_max": m.v_max, "a_max": m.a_max}
            if math.isfinite(m.j_max):
                d["j_max"] = m.j_max
            if m.dwell:
                d["dwell"] = m.dwell
            out.append(d)
        return {"move": out}

    def describe(self, units: Mapping[str, str] | None = None) -> str:
        """One line for notes and the report, in the axis's ``units`` (ident.json's).

        The profile itself is numbers in the axis's position unit (the spec does not say
        which); ``units`` words them.  Without it the axis of
        :func:`commission.units.axis_units_context` (default m), as every label.
        """
        q, v, a = (unit(k, units) for k in ("q", "v", "a"))
        what = (f"{len(self.moves)} point-to-point move{'s' if len(self.moves) != 1 else ''}" if self.kind == "moves"
                else f"the profile {self.path}")
        return (f"{what}: {self.end:.4g} s, peak |v| {self.v_peak:.4g} {v}, peak |a| {self.a_peak:.4g} "
                f"{a.replace('²', '^2')}, span {self.span:.4g} {q}")


def _num(source: str, path: str, raw: Any, unit: str, lo: float, hi: float) -> float:
    u = f" {unit}" if unit else ""
    if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
        raise SpecError(f"{source}: {path} = {raw!r}: expected a finite number{u and ' in' + u}")
    val = float(raw)
    if not lo <= val <= hi:
        raise SpecError(f"{source}: {path} = {val!r}{u} is outside the accepted range [{lo:g}, {hi:g}]{u}")
    return val


def parse_moves(raw: Any, source: str, prefix: str = "") -> UserProfile:
    """``[[trajectory.move]]`` tables -> :class:`UserProfile`.

    Errors name the table as ``trajectory.move[N]`` (N from 1, in file order) and the key.

    Raises
    ------
    SpecError
    """
    base = f"{prefix}trajectory.move"
    if not isinstance(raw, list) or not raw:
        raise SpecError(f"{source}: {base}: expected one or more [[trajectory.move]] tables, got {raw!r}")
    if len(raw) > MAX_MOVES:
        raise SpecError(f"{source}: {base}: {len(raw)} moves, more than the {MAX_MOVES} accepted")
    moves: list[_traj.Move] = []
    for i, tbl in enumerate(raw, start=1):
        path = f"{base}[{i}]"
        if not isinstance(tbl, Mapping):
            raise SpecError(f"{source}: {path}: expected a table with to, v_max, a_max, got {tbl!r}")
        for key in tbl:
            if key not in MOVE_KEYS:
                raise SpecError(f"{source}: {path}.{key}: unknown key (known in a move: {', '.join(MOVE_KEYS)})")
        vals: dict[str, float] = {}
        for key, (required, unit, lo, hi) in MOVE_KEYS.items():
            if key not in tbl:
                if required:
                    raise SpecError(f"{source}: {path}.{key}: missing ({unit}; every move needs to, v_max, a_max)")
                continue
            vals[key] = _num(source, f"{path}.{key}", tbl[key], unit, lo, hi)
        moves.append(_traj.Move(to=vals["to"], v_max=vals["v_max"], a_max=vals["a_max"],
                                j_max=vals.get("j_max", math.inf), dwell=vals.get("dwell", 0.0)))
    with_j = [("j_max" in t) for t in raw]
    if any(with_j) and not all(with_j):
        i = with_j.index(False) + 1
        raise SpecError(f"{source}: {base}[{i}].j_max: missing while other moves give one; give j_max to every "
                        f"move (an S-curve) or to none (a trapezoid)")
    sched, peaks = _traj.scurve_schedule(moves)
    pos = [0.0] + [m.to for m in moves]
    if max(pos) == min(pos):
        raise SpecError(f"{source}: {base}[1].to = {moves[0].to!r} m: the moves do not move (every target is the "
                        f"start, 0 m)")
    text = repr([(m.to, m.v_max, m.a_max, m.j_max, m.dwell) for m in moves]).encode()
    return UserProfile(kind="moves", label=f"{base} ({len(moves)} move{'s' if len(moves) != 1 else ''})", path=None,
                       sha256=hashlib.sha256(text).hexdigest(), end=float(sched.t_switch[-1]),
                       v_peak=max(p[0] for p in peaks), a_peak=max(p[1] for p in peaks),
                       span=max(pos) - min(pos), moves=tuple(moves))


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.float64)
    a.setflags(write=False)
    return a


def read_profile_file(name: str, source: str, key_path: str, base_dir: str,
                      expect_sha256: str | None = None) -> UserProfile:
    """Read a profile CSV (module docstring) -> :class:`UserProfile`.

    Parameters
    ----------
    name : str
        As written in the spec; relative to ``base_dir``.
    source, key_path : str
        The spec file and the key (``trajectory.file``), for messages about the key.
    base_dir : str
        Folder of the spec file.
    expect_sha256 : str, optional
        The digest tune read (tuning.json): a changed file is refused.

    Raises
    ------
    InputFileError
        Missing or unreadable (naming the path).
    SpecError
        A bad header, row or column (naming the file, the row as a line number with the
        header as row 1, and the column), a profile that does not start and end at rest, or
        a changed file.
    """
    from commission.infra.files import read_input_bytes  # the project's checked reader

    path = os.path.abspath(os.path.join(base_dir, os.path.expanduser(name)))
    data = read_input_bytes(path, MAX_PROFILE_BYTES)
    digest = hashlib.sha256(data).hexdigest()
    if expect_sha256 is not None and digest != expect_sha256:
        raise SpecError(f"{source}: {key_path} = {path!r}: the file changed since tune read it (sha256 {digest[:12]}... "
                        f"instead of {expect_sha256[:12]}...); tune again with it")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise SpecError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    header, cols, data_lines = _profile_columns(text, path)
    if header is None:
        raise SpecError(f"{path}: empty (a profile has a header t,q[,v,a] and one row per sample)")
    n = len(cols[0])
    if n < 2:
        raise SpecError(f"{path}: {n} data rows; a profile needs at least 2")
    arr = {c: np.asarray(cols[j], dtype=np.float64) for j, c in enumerate(header)}
    t = arr["t"]
    dt = np.diff(t)
    bad = np.flatnonzero(~(dt > 0))
    if bad.size:
        k = int(bad[0]) + 1
        raise SpecError(f"{path}: row {data_lines[k]}, column t: {float(t[k])!r} s is not after the previous row's "
                        f"{float(t[k - 1])!r} s (t must increase strictly)")
    t = t - t[0]
    q = arr["q"]
    v = arr["v"] if "v" in arr else np.gradient(q, t)
    a = arr["a"] if "a" in arr else np.gradient(v, t)
    v_peak = float(np.max(np.abs(v)))
    a_peak = float(np.max(np.abs(a)))
    span = float(np.max(q) - np.min(q))
    if not (v_peak > 0 and span > 0):
        raise SpecError(f"{path}: the profile does not move (column q is constant)")
    vcol = "v" if "v" in arr else "v (the differences of q)"
    for k in (0, n - 1):
        if abs(v[k]) > REST_FRACTION * v_peak:
            where = "start" if k == 0 else "end"
            raise SpecError(f"{path}: row {data_lines[k]}, column {vcol}: {v[k]:.4g} m/s; the profile must {where} at "
                            f"rest (|v| <= {REST_FRACTION:g} x its peak {v_peak:.4g} m/s)")
    return UserProfile(kind="file", label=f"{key_path} = {name!r}", path=path, sha256=digest, end=float(t[-1]),
                       v_peak=v_peak, a_peak=a_peak, span=span, t=_frozen(t), q=_frozen(q), v=_frozen(v),
                       a=_frozen(a))


def _profile_columns(text: str, path: str) -> tuple[list[str] | None, list[list[float]], list[int]]:
    """The header, the columns and the line number of each data row of a profile CSV (checked cell by cell).

    The header is row 1 and blank lines are skipped; ``header`` is None for a file without rows.
    """
    rows = csv.reader(io.StringIO(text))
    header: list[str] | None = None
    cols: list[list[float]] = []
    data_lines: list[int] = []  # line number of each data row (the header is row 1; blank lines skipped)
    line = 0
    for row in rows:
        line += 1
        if not row or all(not c.strip() for c in row):
            continue
        if header is None:
            header = [c.strip() for c in row]
            for c in header:
                if c not in FILE_COLUMNS:
                    raise SpecError(f"{path}: row {line}, column {c!r}: unknown column (a profile has the columns "
                                    f"t, q and optionally v, a)")
            for c in ("t", "q"):
                if c not in header:
                    raise SpecError(f"{path}: row {line}: no column {c!r} in the header {','.join(header)} "
                                    f"(a profile has the columns t, q and optionally v, a)")
            if len(set(header)) != len(header):
                raise SpecError(f"{path}: row {line}: a column is named twice in the header {','.join(header)}")
            cols = [[] for _ in header]
            continue
        if len(row) != len(header):
            raise SpecError(f"{path}: row {line}: {len(row)} values, the header names {len(header)}")
        if len(cols[0]) >= MAX_PROFILE_ROWS:
            raise SpecError(f"{path}: more than {MAX_PROFILE_ROWS} rows")
        for j, cell in enumerate(row):
            try:
                x = float(cell)
            except ValueError:
                x = math.nan
            if not math.isfinite(x):
                shown = cell.strip() if len(cell.strip()) <= 40 else cell.strip()[:40] + "..."
                raise SpecError(f"{path}: row {line}, column {header[j]}: {shown!r} is not a finite number")
            cols[j].append(x)
        data_lines.append(line)
    return header, cols, data_lines


def parse_profile(table: Mapping[str, Any], source: str, prefix: str = "") -> UserProfile | None:
    """The user profile of a ``[trajectory]`` table (``file`` or ``move``), or None when it has neither.

    The file's path is relative to the folder of ``source`` (the spec file); tuning.json
    stores it absolute with its sha256 (``file_sha256``), which validate checks.

    Raises
    ------
    SpecError, InputFileError
    """
    has_file, has_moves = "file" in table, "move" in table
    if "file_sha256" in table and not has_file:
        raise SpecError(f"{source}: {prefix}trajectory.file_sha256: given without trajectory.file")
    if has_file and has_moves:
        raise SpecError(f"{source}: {prefix}trajectory.file and [[trajectory.move]]: give the profile one way, not both")
    if has_moves:
        return parse_moves(table["move"], source, prefix)
    if not has_file:
        return None
    name = table["file"]
    if not isinstance(name, str) or not name.strip():
        raise SpecError(f"{source}: {prefix}trajectory.file = {name!r}: expected a file name (a CSV t,q[,v,a])")
    sha = table.get("file_sha256")
    if sha is not None and not (isinstance(sha, str) and len(sha) == 64
                                and all(c in "0123456789abcdef" for c in sha)):
        raise SpecError(f"{source}: {prefix}trajectory.file_sha256 = {sha!r}: expected 64 lowercase hex digits")
    base = os.path.dirname(os.path.abspath(source)) if source and not source.startswith("spec (") else os.getcwd()
    return read_profile_file(name, source, f"{prefix}trajectory.file", base, sha)


def profile_keys() -> Sequence[str]:
    """The ``[trajectory]`` keys that give a profile (not numbers of the envelope)."""
    return ("file", "file_sha256", "move")
