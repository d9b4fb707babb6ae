"""``sigma-des tune`` end to end at tiny scale, the fitted file in ``compare``'s scenario,
and exit status 2 with the key named for every kind of bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sigma_des.agents.presets import preset
from sigma_des.cli import main
from sigma_des.config import load
from sigma_des.factory import make_dynamics
from sigma_des.tuning.flightlog import write_csv
from sigma_des.tuning.synth import fly


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    d = tmp_path_factory.mktemp("logs")
    a = write_csv(fly("quadrotor", "quadrotor", duration=3.0, seed=1), d / "tune.csv")
    b = write_csv(fly("quadrotor", "quadrotor", duration=3.0, seed=2, variant=1), d / "val.csv")
    return a, b


def test_tune_writes_fitted_file_usable_by_compare(logs: tuple[Path, Path], tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    init = tmp_path / "init.toml"
    init.write_text('dynamics = "quadrotor"\n[params]\nixx = 0.025\n')
    out = tmp_path / "out"
    rc = main(["tune", "--dynamics", "quadrotor", "--log", str(logs[0]), "--validate",
               str(logs[1]), "--init", str(init), "--set", "tune.population=8",
               "--set", "tune.generations=3", "--set", "tune.params=['ixx','iyy']",
               "--out", str(out)])
    assert rc == 0
    rep = json.loads((out / "report.json").read_text())
    assert [g["name"] for g in rep["genes"]] == ["ixx", "iyy"]
    assert rep["genes"][0]["start"] == 0.025
    assert rep["fitness_best"] <= rep["fitness_start"]
    assert rep["evaluations"] == sum(h["evals"] for h in rep["history"])
    for name in ("tuning", "validation"):
        assert set(rep[name]) >= {"initial", "tuned"}
        assert rep[name]["tuned"]["pitch_channel"] == "theta"
    assert "R²" in capsys.readouterr().out
    sc = load(None, [f"dynamics_params={out / 'fitted.toml'}"])
    model = make_dynamics(sc)
    fitted = {g["name"]: g["fitted"] for g in rep["genes"]}
    assert model.params.ixx == fitted["ixx"] and model.params.iyy == fitted["iyy"]  # type: ignore
    assert model.params.izz == preset("quadrotor").izz  # type: ignore[attr-defined]


def _run_bad(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(args) == 2
    return capsys.readouterr().err


def test_bad_input_exits_2_naming_the_key(logs: tuple[Path, Path], tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    base = ["tune", "--dynamics", "quadrotor", "--log", str(logs[0]), "--out", str(tmp_path)]
    broken = tmp_path / "broken.csv"
    lines = logs[0].read_text().splitlines()
    head = lines[0].split(",")
    k = head.index("q")
    broken.write_text("\n".join(",".join(c for i, c in enumerate(ln.split(",")) if i != k)
                                for ln in lines) + "\n")
    err = _run_bad(["tune", "--dynamics", "quadrotor", "--log", str(broken), "--out",
                    str(tmp_path)], capsys)
    assert "column 'q'" in err and "missing" in err and "Traceback" not in err
    err = _run_bad(base + ["--set", "tune.params=['ixx']", "--set", "tune.lower=[0.03]",
                           "--set", "tune.upper=[0.01]"], capsys)
    assert "tune.lower[0]" in err and "lower bound 0.03 > upper bound 0.01" in err
    err = _run_bad(base + ["--set", "tune.params=['ixx','wingspan']"], capsys)
    assert "tune.params[1]" in err and "unknown parameter 'wingspan'" in err
    err = _run_bad(base + ["--set", "tune.popsize=4"], capsys)
    assert "tune.popsize" in err and "unknown key" in err
    err = _run_bad(base[:2] + ["blimp"] + base[3:], capsys)
    assert "--dynamics" in err
    bad_init = tmp_path / "bad.toml"
    bad_init.write_text('dynamics = "quadrotor"\n[params]\nwingspan = 2.0\n')
    err = _run_bad(base + ["--init", str(bad_init)], capsys)
    assert "params.wingspan" in err
    err = _run_bad(["compare", "--set", f"dynamics_params={bad_init}"], capsys)
    assert "dynamics_params" in err and "params.wingspan" in err
    err = _run_bad(["compare", "--set", "dynamics=pointmass", "--set",
                    f"dynamics_params={bad_init}"], capsys)
    assert "dynamics_params" in err and "pointmass" in err
