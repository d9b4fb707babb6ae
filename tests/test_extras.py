"""A missing optional package: one line naming the extra, exit 2, no traceback (issue 22.5)."""

from __future__ import annotations

import pickle
import subprocess
import sys
from pathlib import Path

import pytest

from sigma_des.cli import main
from sigma_des.extras import EXTRAS, MissingExtra, missing_extra, need

# The child hides one package (``sys.modules[name] = None`` makes importing it fail as if
# it were not installed) and runs the command line.
_RUN = ("import sys; sys.modules[sys.argv[1]] = None; from sigma_des.cli import main; "
        "raise SystemExit(main(sys.argv[2:]))")


@pytest.mark.parametrize(("hidden", "argv", "extra", "instead"), [
    ("orjson", ["compare", "--set", "nodes=2", "--record", "x.mcap"], "record", ""),
    ("mcap", ["replay", "x.mcap", "--rate", "10", "--out", "t.csv"], "record", ""),
    ("dask", ["sweep", "--set", "nodes=2", "--out", "sw"], "experiments", "--in-process"),
    ("jsbsim", ["compare", "--set", 'dynamics="jsbsim:c172x"'], "physics", ""),
    ("jsbsim", ["flightlog", "--out", "t.csv"], "physics", ""),
    ("paho", ["live", "--set", "nodes=2"], "live", ""),
    ("matplotlib", ["compare", "--set", "nodes=2", "--out", "o"], "experiments", "--no-plots"),
])
def test_a_missing_extra_is_one_line_and_exit_2(tmp_path: Path, hidden: str, argv: list[str],
                                                extra: str, instead: str) -> None:
    r = subprocess.run([sys.executable, "-c", _RUN, hidden, *argv], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert f"'{hidden}'" in lines[0] and f"pip install 'sigma-des[{extra}]'" in lines[0]
    assert instead in lines[0]
    # checked before any work: nothing was written
    assert not any(p.name in ("o", "x.mcap", "t.csv") for p in tmp_path.iterdir())


def test_one_met_later_is_turned_into_the_same_line(monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """A command that imports an extra's package mid-run gets the one-line error too."""
    import sigma_des.warmup.cli as warmup_cli

    def fails(args: object) -> int:
        raise ModuleNotFoundError("No module named 'dask.distributed'", name="dask.distributed")

    monkeypatch.setattr(warmup_cli, "run", fails)
    assert main(["warmup"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("sigma-des: error: warmup: needs the optional package 'dask', which is not "
                   "installed: pip install 'sigma-des[experiments]'")


def test_a_missing_module_of_no_extra_is_not_hidden(monkeypatch: pytest.MonkeyPatch) -> None:
    import sigma_des.warmup.cli as warmup_cli

    def fails(args: object) -> int:
        raise ModuleNotFoundError("No module named 'sigma_des.gone'", name="sigma_des.gone")

    monkeypatch.setattr(warmup_cli, "run", fails)
    with pytest.raises(ModuleNotFoundError):
        main(["warmup"])


def test_need_and_the_command_s_own_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    need("x", "numpy")  # installed: no error
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(MissingExtra) as ei:
        need("live", "pandas", extra="live")
    assert ei.value.key == "live" and "sigma-des[live]" in ei.value.reason
    e = missing_extra(ModuleNotFoundError(name="pandas"), "replay", "record")
    assert e is not None and e.extra == "record"
    e = missing_extra(ModuleNotFoundError(name="pandas"), "sweep", "tuning")  # not pandas's
    assert e is not None and e.extra == EXTRAS["pandas"][0]
    assert missing_extra(ModuleNotFoundError(name="yaml"), "x") is None


def test_the_errors_survive_a_worker_process() -> None:
    """Raised in a ``compare --jobs`` worker, they are pickled back to the parent."""
    from sigma_des.errors import ConfigError

    e = pickle.loads(pickle.dumps(MissingExtra("--record", "orjson", instead="not that")))
    assert (type(e), e.key, e.module, e.extra, str(e)) == (
        MissingExtra, "--record", "orjson", "record",
        "--record: needs the optional package 'orjson', which is not installed: "
        "pip install 'sigma-des[record]', or not that")
    c = pickle.loads(pickle.dumps(ConfigError("a.b", "bad")))
    assert (c.key, c.reason) == ("a.b", "bad")


_IMPORT = ("import sys; sys.modules[sys.argv[1]] = None\n"
           "try:\n    exec(sys.argv[2])\n"
           "except ImportError as e:\n"
           "    print(type(e).__name__, e.name, isinstance(e, ImportError), str(e), sep='|')\n")


@pytest.mark.parametrize(("hidden", "code", "extra"), [
    ("pettingzoo", "from sigma_des.env import SwarmEnv", "env"),
    ("gymnasium", "import sigma_des.env", "env"),
    ("mcap", "from sigma_des.record import read_table", "record"),
    ("orjson", "from sigma_des.record.parts import RecordParts", "record"),
])
def test_a_python_import_of_a_missing_extra_names_it(hidden: str, code: str, extra: str) -> None:
    r = subprocess.run([sys.executable, "-c", _IMPORT, hidden, code], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    package = "sigma_des." + extra
    assert r.stdout == (f"ExtraImportError|{hidden}|True|{package} needs the optional package "
                        f"'{hidden}', which is not installed: pip install 'sigma-des[{extra}]'\n")
