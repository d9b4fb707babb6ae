"""Grid parsing and up-front validation; ``sigma-des sweep`` exit status and outputs."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from sweep_helpers import CountingTask, tiny_base

from sigma_des import ConfigError
from sigma_des.cli import main
from sigma_des.sweep import Sweep, expand_grid, parse_grid_args, parse_seeds
from sigma_des.sweep.grid import split_values

TINY_SETS = ["--set", "hosts=1", "--set", "duration=0.3", "--set", "warmup=0.1"]


def test_grid_values_are_toml_like_set() -> None:
    g = parse_grid_args(
        [
            "nodes=10,20",
            "net.transport=datagram,'stream'",
            "net.host_link.latency={dist='normal', mean=0.03, std=0.01},0.001",
            "bides.adaptation=true,false",
            "faults=[],[{kind='crash', node=1, start=0.2}]",
        ]
    )
    assert g["nodes"] == [10, 20]
    assert g["net.transport"] == ["datagram", "stream"]
    assert g["net.host_link.latency"] == [{"dist": "normal", "mean": 0.03, "std": 0.01}, 0.001]
    assert g["bides.adaptation"] == [True, False]
    assert g["faults"] == [[], [{"kind": "crash", "node": 1, "start": 0.2}]]
    assert split_values("a, 'b,c', [1, 2]") == ["a", "'b,c'", "[1, 2]"]


def test_expand_grid_is_the_product_first_key_slowest() -> None:
    pts = expand_grid({"nodes": [3, 4], "net.qos": [0, 1]})
    assert pts == [
        {"nodes": 3, "net.qos": 0},
        {"nodes": 3, "net.qos": 1},
        {"nodes": 4, "net.qos": 0},
        {"nodes": 4, "net.qos": 1},
    ]
    assert expand_grid({}) == [{}]
    assert expand_grid([{"nodes": 3, "hosts": 1}]) == [{"nodes": 3, "hosts": 1}]


@pytest.mark.parametrize(
    ("grid", "key", "words"),
    [
        ({"nodse": [3]}, "nodse", "unknown key"),
        ({"nodes": [3, 0]}, "nodes", "nodes=0"),
        ({"net.host_link.loss.p": [0.1, 1.0]}, "net.host_link.loss.p", "[0, 1)"),
        ({"nodes": [3], "hosts": [1, 5]}, "hosts", "hosts=5"),
        ({"nodes.x": [1]}, "nodes", "not a table"),
        ({"seed": [1, 2]}, "seed", "--seeds"),
        ({"methods": [["none"]]}, "methods", "--methods"),
        ({"nodes": []}, "nodes", "no values"),
    ],
)
def test_bad_grid_fails_before_any_work(
    tmp_path: Path, grid: dict[str, list[object]], key: str, words: str
) -> None:
    task = CountingTask()
    store = tmp_path / "s.sqlite"
    with pytest.raises(ConfigError) as ei:
        Sweep(tiny_base(), grid, ["none"], 2, store, task=task)
    assert ei.value.key == key
    assert words in str(ei.value)
    assert task.calls == [] and not store.exists()


def test_seeds_and_methods_syntax() -> None:
    assert parse_seeds("5") == [1, 2, 3, 4, 5]
    assert parse_seeds(3) == [1, 2, 3]
    assert parse_seeds("7,3,11") == [7, 3, 11]
    assert parse_seeds("3..5") == [3, 4, 5]
    for bad in ("x", "1,1", "0", "-1,2"):
        with pytest.raises(ConfigError) as ei:
            parse_seeds(bad)
        assert ei.value.key == "seeds"
    with pytest.raises(ConfigError) as ei:
        Sweep(tiny_base(), {}, "none,fast", 1, "unused.sqlite")
    assert ei.value.key == "methods"


@pytest.mark.parametrize(
    ("args", "key"),
    [
        (["--grid", "nodse=3,4"], "nodse"),
        (["--grid", "nodes=3,4", "--grid", "net.qos=0,2"], "net.qos"),
        (["--grid", "nodes=3", "--seeds", "a,b"], "seeds"),
        (["--grid", "nodes=3", "--methods", "none,slow"], "methods"),
        (["--grid", "nodes=3,4", "--grid", "nodes=5"], "nodes"),
    ],
)
def test_cli_bad_input_exits_2_naming_the_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], key: str
) -> None:
    store = tmp_path / "s.sqlite"
    rc = main(["sweep", *TINY_SETS, *args, "--in-process", "--store", str(store)])
    assert rc == 2
    err = capsys.readouterr().err
    assert err.startswith(f"sigma-des: error: {key}:")
    assert not store.exists()


def test_cli_sweep_in_process_writes_tables_and_resumes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    argv = ["sweep", *TINY_SETS, "--grid", "nodes=3,4", "--methods", "lockstep"]
    argv += ["--seeds", "2", "--in-process", "--no-progress", "--out", str(out)]
    assert main(argv) == 0
    assert "4 run now (4 ok, 0 failed)" in capsys.readouterr().out
    assert (out / "sweep.sqlite").exists()
    with (out / "runs.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["nodes", "config_hash", "seed", "method", "metric", "value", "unit"]
    assert {(r["nodes"], r["seed"], r["method"]) for r in rows if r["metric"] == "aoi_mean"} == {
        (n, s, "lockstep") for n in "34" for s in "12"
    }
    with (out / "aggregate.csv").open() as fh:
        agg = list(csv.DictReader(fh))
    assert list(agg[0])[-4:] == ["n", "mean", "std", "ci95"]
    assert {r["n"] for r in agg if r["metric"] == "aoi_mean"} == {"2"}
    # run-cost figures live in wall.csv only (issue 9.12)
    assert not {r["metric"] for r in rows + agg} & {"wall_s", "events_per_s", "peak_rss_mb"}
    with (out / "wall.csv").open() as fh:
        wall = list(csv.DictReader(fh))
    assert {r["metric"] for r in wall} == {
        "wall_s", "events", "events_per_s", "peak_rss_mb", "speed_x_realtime"
    }
    assert len(wall) == 4 * 5
    assert main(argv) == 0
    assert "4 already done, 0 run now" in capsys.readouterr().out
