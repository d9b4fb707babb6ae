"""Flight logs for model tuning: the CSV format, its validation and resampling.

A flight log is what the paper's step 1 records in offboard mode: the
autopilot's **control signals** (what the actuators were told) and the
**measured state** (external positioning + attitude), at the same timestamps.
CSV columns (header row required, any order, extra columns are an error):

===============================  ========  ==========================================
column                           unit      allowed range
===============================  ========  ==========================================
``t``                            s         strictly increasing, >= 0
``omega0`` .. ``omega3``         rad/s     [0, 5000]; rotor-speed commands (a fixed
                                           wing has ``omega0`` only: its propeller)
``delta_a, delta_e, delta_r``    rad       [-1, 1]; surface commands (fixed wing only)
``x, y``                         m         |.| <= 1e6 (north, east)
``h``                            m         [-500, 20000] (altitude, up)
``u, v, w``                      m/s       |.| <= 200 (body-axis velocity)
``phi, theta, psi``              rad       phi, psi in [-2 pi, 2 pi]; theta in [-pi/2, pi/2]
``p, q, r``                      rad/s     |.| <= 50 (body rates)
===============================  ========  ==========================================

Which actuator columns are required depends on the aircraft kind
(:data:`ACTUATOR_COLUMNS`). Every problem raises
:class:`~sigma_des.errors.ConfigError` naming the file, column and row.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from sigma_des.errors import ConfigError
from sigma_des.guard import read_text

__all__ = ["FlightLog", "STATE_COLUMNS", "ACTUATOR_COLUMNS", "read_csv", "write_csv",
           "resample", "check_log"]

#: Measured-state columns, in the order of ``observe_state`` (aircraft.py).
STATE_COLUMNS: tuple[str, ...] = ("u", "v", "w", "phi", "theta", "psi", "p", "q", "r",
                                  "x", "y", "h")
#: Control-signal columns per aircraft kind.
ACTUATOR_COLUMNS: dict[str, tuple[str, ...]] = {
    "quadrotor": ("omega0", "omega1", "omega2", "omega3"),
    "fixedwing": ("omega0", "delta_a", "delta_e", "delta_r"),
}
_HALF_PI = math.pi / 2 + 1e-9
_RANGES: dict[str, tuple[float, float]] = {
    "omega0": (0.0, 5000.0), "omega1": (0.0, 5000.0), "omega2": (0.0, 5000.0),
    "omega3": (0.0, 5000.0), "delta_a": (-1.0, 1.0), "delta_e": (-1.0, 1.0),
    "delta_r": (-1.0, 1.0), "x": (-1e6, 1e6), "y": (-1e6, 1e6), "h": (-500.0, 20000.0),
    "u": (-200.0, 200.0), "v": (-200.0, 200.0), "w": (-200.0, 200.0),
    "phi": (-2 * math.pi, 2 * math.pi), "theta": (-_HALF_PI, _HALF_PI),
    "psi": (-2 * math.pi, 2 * math.pi), "p": (-50.0, 50.0), "q": (-50.0, 50.0),
    "r": (-50.0, 50.0),
}
MIN_ROWS = 10


@dataclass(frozen=True)
class FlightLog:
    """A validated flight log.

    Attributes:
        kind: ``quadrotor`` or ``fixedwing`` (selects the actuator columns).
        t: ``(T,)`` timestamps (s), strictly increasing.
        act: ``(T, len(ACTUATOR_COLUMNS[kind]))`` control signals.
        obs: ``(T, 12)`` measured state, columns :data:`STATE_COLUMNS`.
        source: where it came from (file name for messages).
    """

    kind: str
    t: NDArray[np.float64]
    act: NDArray[np.float64]
    obs: NDArray[np.float64]
    source: str = "<memory>"

    def __post_init__(self) -> None:
        check_log(self)

    @property
    def columns(self) -> tuple[str, ...]:
        """All column names in file order."""
        return ("t", *ACTUATOR_COLUMNS[self.kind], *STATE_COLUMNS)

    @property
    def duration(self) -> float:
        """Flight time ``T`` of the paper's eq. (13) (s)."""
        return float(self.t[-1] - self.t[0])

    @property
    def distance(self) -> float:
        """Flight distance ``s`` of eq. (13): path length of the logged positions (m)."""
        d = np.diff(self.obs[:, 9:12], axis=0)
        return float(np.sqrt((d * d).sum(axis=1)).sum())

    def column(self, name: str) -> NDArray[np.float64]:
        """One column by name."""
        if name == "t":
            return self.t
        acts = ACTUATOR_COLUMNS[self.kind]
        if name in acts:
            return self.act[:, acts.index(name)]
        return self.obs[:, STATE_COLUMNS.index(name)]


def _bad(src: str, col: str, why: str) -> ConfigError:
    return ConfigError(f"{src}: column '{col}'", why)


def check_log(log: FlightLog) -> None:
    """Validate shapes, timestamps, NaNs and unit ranges (raises ConfigError)."""
    src = log.source
    if log.kind not in ACTUATOR_COLUMNS:
        raise ConfigError(f"{src}: kind",
                          f"must be one of {sorted(ACTUATOR_COLUMNS)}, got {log.kind!r}")
    n = log.t.shape[0]
    acts = ACTUATOR_COLUMNS[log.kind]
    if log.t.ndim != 1 or log.act.shape != (n, len(acts)) or log.obs.shape != (n, 12):
        raise ConfigError(src, f"shapes t {log.t.shape}, act {log.act.shape}, "
                          f"obs {log.obs.shape} do not match ({n},), ({n}, {len(acts)}), "
                          f"({n}, 12)")
    if n < MIN_ROWS:
        raise ConfigError(src, f"needs at least {MIN_ROWS} rows, got {n}")
    for name, col in [("t", log.t)] + [(c, log.act[:, i]) for i, c in enumerate(acts)] + [
            (c, log.obs[:, i]) for i, c in enumerate(STATE_COLUMNS)]:
        bad = np.flatnonzero(~np.isfinite(col))
        if bad.size:
            raise _bad(src, name, f"NaN/inf at data row {int(bad[0]) + 1}")
        if name == "t":
            continue
        lo, hi = _RANGES[name]
        out = np.flatnonzero((col < lo) | (col > hi))
        if out.size:
            i = int(out[0])
            raise _bad(src, name, f"value {float(col[i])!r} at data row {i + 1} outside "
                       f"[{lo:g}, {hi:g}] (units: see sigma_des/tuning/flightlog.py)")
    if log.t[0] < 0:
        raise _bad(src, "t", f"must be >= 0, got {float(log.t[0])!r} at data row 1")
    dt = np.diff(log.t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        what = "duplicated" if dt[i - 1] == 0 else "non-monotone (decreasing)"
        raise _bad(src, "t", f"{what} timestamp {float(log.t[i])!r} at data row {i + 1}")


def read_csv(path: str | Path, kind: str) -> FlightLog:
    """Load and validate a CSV flight log of aircraft ``kind`` (see module docstring)."""
    path = Path(path)
    src = str(path)
    if kind not in ACTUATOR_COLUMNS:
        raise ConfigError("--dynamics", f"must be one of {sorted(ACTUATOR_COLUMNS)}, got {kind!r}")
    text = read_text(path, src, "CSV flight log")
    try:
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as e:
        raise ConfigError(src, f"not a CSV file: {e}") from None
    if not rows:
        raise ConfigError(src, "empty file (a header row is required)")
    head = [h.strip() for h in rows[0]]
    need = ("t", *ACTUATOR_COLUMNS[kind], *STATE_COLUMNS)
    for c in need:
        if c not in head:
            raise _bad(src, c, f"missing; a {kind} log needs columns {', '.join(need)}")
    extra = [h for h in head if h not in need]
    if extra:
        raise _bad(src, extra[0], f"unknown; allowed columns: {', '.join(need)}")
    if len(set(head)) != len(head):
        dup = next(h for h in head if head.count(h) > 1)
        raise _bad(src, dup, "appears twice in the header")
    data = np.empty((len(rows) - 1, len(head)))
    for i, row in enumerate(rows[1:]):
        if len(row) != len(head):
            raise ConfigError(f"{src}: data row {i + 1}",
                              f"has {len(row)} fields, the header has {len(head)}")
        for j, v in enumerate(row):
            try:
                data[i, j] = float(v)
            except ValueError:
                raise _bad(src, head[j], f"not a number {v!r} at data row {i + 1}") from None
    idx = {h: j for j, h in enumerate(head)}
    return FlightLog(kind=kind, t=data[:, idx["t"]].copy(),
                     act=data[:, [idx[c] for c in ACTUATOR_COLUMNS[kind]]].copy(),
                     obs=data[:, [idx[c] for c in STATE_COLUMNS]].copy(), source=src)


def write_csv(log: FlightLog, path: str | Path) -> Path:
    """Write ``log`` in the documented CSV format (full float precision)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = np.column_stack([log.t, log.act, log.obs])
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(log.columns)
        for row in data:
            w.writerow([repr(float(v)) for v in row])
    return path


def resample(log: FlightLog, rate: float) -> FlightLog:
    """The log on a uniform grid at ``rate`` Hz from its first timestamp.

    States are interpolated linearly (angles after unwrapping, then wrapped back
    to (-pi, pi]); control signals are sample-and-hold (the autopilot's value
    in force at each instant), as a replay at the same timestamps would see them.
    """
    if not rate > 0:
        raise ConfigError("tune.rate", f"must be > 0 Hz, got {rate}")
    n = int(math.floor(log.duration * rate + 1e-9)) + 1
    if n < MIN_ROWS:
        raise ConfigError("tune.rate", f"{rate} Hz gives {n} samples over "
                          f"{log.duration:.3f} s; at least {MIN_ROWS} needed")
    t = log.t[0] + np.arange(n) / rate
    obs = np.empty((n, 12))
    for j, c in enumerate(STATE_COLUMNS):
        col = log.obs[:, j]
        if c in ("phi", "psi"):
            obs[:, j] = np.angle(np.exp(1j * np.interp(t, log.t, np.unwrap(col))))
        else:
            obs[:, j] = np.interp(t, log.t, col)
    k = np.clip(np.searchsorted(log.t, t + 1e-12, side="right") - 1, 0, len(log.t) - 1)
    return FlightLog(kind=log.kind, t=t, act=log.act[k].copy(), obs=obs, source=log.source)
