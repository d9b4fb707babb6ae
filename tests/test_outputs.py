"""Output files: deterministic results.csv, wall.csv apart, --out checked before the
run, all-or-none writes (issue 9.7 and 9.12)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sigma_des.api as api
from sigma_des import ConfigError, compare
from sigma_des.cli import main
from sigma_des.metrics.collector import WALL_METRICS
from sigma_des.outputs import check_out_dir, write_files
from tests.conftest import tiny

SETS = ["--set", "nodes=2", "--set", "duration=0.3", "--set", "warmup=0.1",
        "--set", "dynamics=pointmass", "--set", "fidelity.enabled=false", "--no-progress",
        "--methods", "none"]


@pytest.mark.parametrize(("mask", "mode"), [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_written_files_get_the_umask_s_mode(tmp_path: Path, mask: int, mode: int) -> None:
    """As ``open`` would make them: ``0666`` less the umask (mkstemp alone gives 0600)."""
    from sigma_des.outputs import umask

    old = os.umask(mask)
    try:
        assert umask() == mask
        paths = write_files(tmp_path, {"a.csv": lambda fh: fh.write("x\n"),
                                       "b.json": lambda fh: fh.write("{}")})
    finally:
        os.umask(old)
    assert [p.stat().st_mode & 0o777 for p in paths] == [mode, mode]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "b.json"]


def test_results_csv_is_identical_for_same_seed(tmp_path: Path) -> None:
    sc = tiny()
    a, b = tmp_path / "a", tmp_path / "b"
    compare(sc, ["none", "lockstep"], progress=False).write(a)
    compare(sc, ["none", "lockstep"], progress=False).write(b)
    assert (a / "results.csv").read_bytes() == (b / "results.csv").read_bytes()
    wall = (a / "wall.csv").read_text()
    for name in WALL_METRICS:
        assert name not in (a / "results.csv").read_text()
        assert f",{name}," in wall


def test_cli_refuses_a_file_as_out_before_running(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    ran = []
    monkeypatch.setattr(api, "compare", lambda *a, **k: ran.append(1))
    assert main(["compare", *SETS, "--out", str(f)]) == 2
    assert main(["compare", *SETS, "--out", str(f / "sub")]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "is an existing file" in err and "lies under" in err
    assert not ran  # refused before any simulation


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_unwritable_directory_is_refused(tmp_path: Path) -> None:
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o500)
    try:
        with pytest.raises(ConfigError) as ei:
            check_out_dir(d)
        assert ei.value.key == "--out" and "cannot write" in ei.value.reason
    finally:
        d.chmod(0o700)


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.integers(0, 2))
def test_a_failed_write_leaves_nothing(tmp_path: Path, failing: int) -> None:
    """Whichever file's writer fails, no final file (and no temporary) is left."""
    d = tmp_path / f"o{failing}"
    d.mkdir(exist_ok=True)

    def ok(fh):  # type: ignore[no-untyped-def]
        fh.write("data\n")

    def bad(fh):  # type: ignore[no-untyped-def]
        fh.write("half")
        raise OSError(28, "No space left on device")

    files = {n: (bad if i == failing else ok) for i, n in enumerate(("a.csv", "b.csv", "c.json"))}
    with pytest.raises(ConfigError) as ei:
        write_files(d, files)
    assert "No space left" in ei.value.reason
    assert list(d.iterdir()) == []
    assert [p.name for p in write_files(d, dict.fromkeys(files, ok))] == list(files)
    assert sorted(p.name for p in d.iterdir()) == sorted(files)


def test_a_ctrl_c_while_compare_writes_is_noted_and_every_file_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The runs are done and the tables written when SIGINT arrives (while the plots are
    drawn): it is noted on stderr, the writes go on, nothing finished is lost."""
    import signal

    import sigma_des.plots as plots

    real = plots.write_plots

    def interrupted(res: api.Results, out: Path) -> list[Path]:
        os.kill(os.getpid(), signal.SIGINT)
        return real(res, out)

    monkeypatch.setattr(plots, "write_plots", interrupted)
    out = tmp_path / "o"
    rc = main(["compare", "--set", "duration=1", "--set", "warmup=0.2", "--set", "nodes=4",
               "--methods", "none", "--no-progress", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert "sigma-des: SIGINT: noted; finishing the clean-up and writes first" in err
    assert (out / "results.csv").exists() and list(out.glob("*.png"))
