"""Flight-log CSV: exact round trip, resampling by hand, and every bad input named."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sigma_des.errors import ConfigError
from sigma_des.tuning.flightlog import (
    ACTUATOR_COLUMNS,
    STATE_COLUMNS,
    FlightLog,
    read_csv,
    resample,
    write_csv,
)


def _log(n: int = 12, kind: str = "quadrotor") -> FlightLog:
    t = np.arange(n) * 0.1
    act = np.full((n, 4), 400.0) + np.arange(n)[:, None]
    if kind == "fixedwing":
        act[:, 1:] = 0.01
    obs = np.zeros((n, 12))
    obs[:, 0] = 1.0 + t              # u
    obs[:, 5] = 3.1 + 0.02 * np.arange(n)   # psi crosses +pi
    obs[:, 5] = np.angle(np.exp(1j * obs[:, 5]))
    obs[:, 9] = 2.0 * t              # x
    obs[:, 11] = 100.0
    return FlightLog(kind, t, act, obs, "mem")


def _write(tmp: Path, head: list[str], rows: list[list[str]]) -> Path:
    p = tmp / "log.csv"
    p.write_text("\n".join([",".join(head)] + [",".join(r) for r in rows]) + "\n")
    return p


def test_round_trip_is_exact(tmp_path: Path) -> None:
    for kind in ACTUATOR_COLUMNS:
        log = _log(kind=kind)
        back = read_csv(write_csv(log, tmp_path / f"{kind}.csv"), kind)
        assert np.array_equal(back.t, log.t)
        assert np.array_equal(back.act, log.act)
        assert np.array_equal(back.obs, log.obs)


def test_duration_and_distance() -> None:
    log = _log()
    assert log.duration == pytest.approx(1.1)
    assert log.distance == pytest.approx(2.2)     # x = 2 t over 1.1 s


def test_resample_holds_controls_and_interpolates_states() -> None:
    log = _log()
    r = resample(log, 20.0)                       # 0.05 s grid over 1.1 s
    assert r.t.shape == (23,)
    assert r.act[1, 0] == 400.0 and r.act[2, 0] == 401.0 and r.act[3, 0] == 401.0
    assert r.column("u")[1] == pytest.approx(1.05)
    # psi interpolated across the +-pi wrap: halfway between 3.1 + 0.2 and 3.1 + 0.22.
    k = 21
    assert r.column("psi")[k] == pytest.approx(math.remainder(3.1 + 0.21, 2 * math.pi))


def _bad(tmp: Path, mutate: object, match: str) -> None:
    log = _log()
    head = list(log.columns)
    rows = [[repr(float(v)) for v in row] for row in np.column_stack([log.t, log.act, log.obs])]
    assert callable(mutate)
    head, rows = mutate(head, rows)
    with pytest.raises(ConfigError, match=match):
        read_csv(_write(tmp, head, rows), "quadrotor")


def test_bad_logs_name_the_column(tmp_path: Path) -> None:
    iq = STATE_COLUMNS.index("q") + 5   # t + 4 actuators before the states
    ip = STATE_COLUMNS.index("phi") + 5

    def drop_q(h: list[str], r: list[list[str]]) -> tuple[list[str], list[list[str]]]:
        return h[:iq] + h[iq + 1:], [x[:iq] + x[iq + 1:] for x in r]

    def dup_t(h: list[str], r: list[list[str]]) -> tuple[list[str], list[list[str]]]:
        r[3][0] = r[2][0]
        return h, r

    def back_t(h: list[str], r: list[list[str]]) -> tuple[list[str], list[list[str]]]:
        r[4][0] = "0.05"
        return h, r

    def nan(h: list[str], r: list[list[str]]) -> tuple[list[str], list[list[str]]]:
        r[5][ip] = "nan"
        return h, r

    def degrees(h: list[str], r: list[list[str]]) -> tuple[list[str], list[list[str]]]:
        r[6][ip] = "30.0"
        return h, r

    def extra(h: list[str], r: list[list[str]]) -> tuple[list[str], list[list[str]]]:
        return h + ["alpha"], [x + ["0"] for x in r]

    def text(h: list[str], r: list[list[str]]) -> tuple[list[str], list[list[str]]]:
        r[1][1] = "fast"
        return h, r

    _bad(tmp_path, drop_q, r"column 'q'.*missing")
    _bad(tmp_path, dup_t, r"column 't'.*duplicated timestamp .* data row 4")
    _bad(tmp_path, back_t, r"column 't'.*non-monotone .* data row 5")
    _bad(tmp_path, nan, r"column 'phi'.*NaN.*data row 6")
    _bad(tmp_path, degrees, r"column 'phi'.*30.0 at data row 7 outside")
    _bad(tmp_path, extra, r"column 'alpha'.*unknown")
    _bad(tmp_path, text, r"column 'omega0'.*not a number 'fast'")


def test_missing_file_and_wrong_kind(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="CSV flight log not found"):
        read_csv(tmp_path / "nope.csv", "quadrotor")
    with pytest.raises(ConfigError, match="--dynamics"):
        read_csv(tmp_path / "nope.csv", "blimp")
