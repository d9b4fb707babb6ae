"""JSBSim minisgs glider logs: bad options exit 2 naming the option, the excitation shapes
by hand, a short log (and the CLI's CSV) is a trimmed, excited glide. The replay check of
the logged surfaces is in tests/lab/studies/test_fixed_wing.py."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sigma_des.cli import main
from sigma_des.errors import ConfigError
from sigma_des.tuning.glider_log import GlideSpec, _3211, _doublet, _sweep, excitation


@pytest.mark.parametrize(("field", "value", "option"), [
    ("aircraft", "c172x", "--aircraft"), ("speed", 30.0, "--speed"),
    ("speed", float("nan"), "--speed"), ("duration", 1.0, "--duration"),
    ("rate", 5.0, "--rate"), ("variant", 3, "--variant"), ("variant", -1, "--variant"),
    ("seed", -1, "--seed"), ("amp_e", 0.5, "--amp-e"), ("amp_a", -0.1, "--amp-a"),
    ("altitude", 50.0, "--altitude"), ("warmup", 61.0, "--warmup"),
    ("speed_step", 7.0, "--speed-step"),
])
def test_bad_spec_names_the_option(field: str, value: object, option: str) -> None:
    with pytest.raises(ConfigError) as ei:
        GlideSpec(**{field: value})  # type: ignore[arg-type]
    assert ei.value.key == option


@pytest.mark.parametrize(("argv", "option"), [
    (["--speed", "30"], "--speed"), (["--variant", "7"], "--variant"),
    (["--aircraft", "F450"], "--aircraft"), (["--duration", "inf"], "--duration"),
])
def test_cli_bad_option_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                argv: list[str], option: str) -> None:
    out = tmp_path / "log.csv"
    assert main(["flightlog", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"sigma-des: error: {option}:")
    assert not out.exists()


def test_excitation_shapes_by_hand() -> None:
    assert [_doublet(t, 1.0, 0.5) for t in (0.9, 1.0, 1.49, 1.5, 1.99, 2.0)] == [
        0.0, 1.0, 1.0, -1.0, -1.0, 0.0]
    # 3-2-1-1 with a 0.3 s unit: +1 for 0.9 s, -1 for 0.6 s, +1, -1 for 0.3 s each.
    assert [_3211(t, 0.0, 0.3) for t in (0.1, 0.85, 0.95, 1.45, 1.55, 1.85, 1.95, 2.2)] == [
        1.0, 1.0, -1.0, -1.0, 1.0, -1.0, -1.0, 0.0]
    # log sweep 1 -> e Hz over 1 s: phase 2 pi (e^x - 1); at x = ln 1.25, sin(2 pi 0.25) = 1.
    assert _sweep(math.log(1.25), 0.0, 1.0, 1.0, math.e) == pytest.approx(1.0)
    assert _sweep(0.0, 0.0, 1.0, 1.0, 2.0) == 0.0 and _sweep(1.0, 0.0, 1.0, 1.0, 2.0) == 0.0
    # programme 0: elevator doublet from 1 s, aileron doublet from 3 s; the programme repeats
    assert excitation(1.2, 0) == (1.0, 0.0) and excitation(3.7, 0) == (0.0, -1.0)
    assert excitation(24.0 + 1.2, 0) == (1.0, 0.0) and excitation(0.5, 0) == (0.0, 0.0)


def test_short_log_is_a_valid_excited_glide(tmp_path: Path) -> None:
    pytest.importorskip("jsbsim")
    from sigma_des.tuning.flightlog import read_csv
    from sigma_des.tuning.glider_log import fly_glider

    log = fly_glider(GlideSpec(duration=4.0, warmup=4.0, noise=False))
    assert log.t.shape == (201,) and log.act.shape == (201, 4)
    assert np.all(log.act[:, 0] == 0.0)                       # no propeller
    assert np.abs(log.act[:, 1:3]).max() < 0.3 and np.abs(log.act[:, 1]).max() > 0.1
    v = np.sqrt((log.obs[:, 0:3] ** 2).sum(axis=1))
    assert abs(v[0] - 10.0) < 0.5 and np.all(np.diff(log.obs[:, 11]) < 0.5)   # trimmed glide
    out = tmp_path / "g.csv"
    assert main(["flightlog", "--duration", "2", "--warmup", "0", "--no-noise",
                 "--out", str(out)]) == 0
    got = read_csv(out, "fixedwing")
    assert got.t.shape == (101,) and got.obs[0, 0] == pytest.approx(10.0, abs=1e-9)
