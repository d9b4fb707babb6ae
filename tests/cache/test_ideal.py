"""The on-disk ideal-run cache: hits are bit-identical, keys separate what differs,
entries are shared across processes, unreadable entries are recomputed."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import sigma_des.api as api
from sigma_des import Scenario
from sigma_des.cache import ideal as ic


def _sc(**kw: object) -> Scenario:
    base = dict(nodes=4, hosts=1, duration=0.3, warmup=0.1, dynamics="pointmass")
    base.update(kw)
    return Scenario(**base)  # type: ignore[arg-type]


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv(ic.ENV_VAR, str(tmp_path))
    return tmp_path / "ideal"


def test_hit_is_bit_identical_and_skips_the_flight(cache: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    sc = _sc()
    t0, p0 = api.fly_ideal(sc)
    t1, p1 = api.ideal_run(sc)  # miss: computes and stores
    assert list(cache.glob("*.npz")) == [cache / f"{ic.cache_key(sc)}.npz"]
    assert np.array_equal(t1, t0) and np.array_equal(p1, p0)

    def boom(_sc: Scenario) -> None:
        raise AssertionError("the cache was not used")

    monkeypatch.setattr(api, "fly_ideal", boom)
    t2, p2 = api.ideal_run(sc)  # hit
    assert t2.dtype == p2.dtype == np.float64
    assert p2.tobytes() == p0.tobytes() and t2.tobytes() == t0.tobytes()
    assert p2.shape == (10, 4, 3)  # 0.3 s at 30 Hz: 0, 1/30, ..., 9/30


def test_key_separates_what_can_change_the_run(tmp_path: Path) -> None:
    sc = _sc()
    k = ic.cache_key(sc)
    assert len(k) == 64
    # not part of the ideal run: the method list and the engine
    assert ic.cache_key(replace(sc, methods=("bides",))) == k
    assert ic.cache_key(replace(sc, engine="events")) == k
    # every other field is
    for other in (replace(sc, nodes=5), replace(sc, duration=0.4), replace(sc, seed=2),
                  replace(sc, f_trig=50.0), replace(sc, dynamics="quadrotor")):
        assert ic.cache_key(other) != k


def test_key_follows_the_dynamics_params_file_contents(tmp_path: Path) -> None:
    f = tmp_path / "fitted.toml"
    f.write_text("a = 1\n")
    d1 = ic._file_digest(str(f))
    f.write_text("a = 2\n")
    assert ic._file_digest(str(f)) != d1
    assert ic._file_digest(str(tmp_path / "missing.toml")) == "unreadable"


def test_switched_off_computes_every_time(tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    calls = []

    def compute(sc: Scenario) -> tuple[np.ndarray, np.ndarray]:
        calls.append(1)
        return np.zeros(1), np.zeros((1, 1, 3))

    for off in ("off", "0", ""):
        monkeypatch.setenv(ic.ENV_VAR, off)
        assert ic.cache_dir() is None
        ic.cached(_sc(), compute)
    assert len(calls) == 3
    monkeypatch.delenv(ic.ENV_VAR)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert ic.cache_dir() == tmp_path / "sigma_des" / "ideal"


def test_unreadable_entry_is_a_miss_and_is_rewritten(cache: Path) -> None:
    sc = _sc()
    t0, p0 = api.fly_ideal(sc)
    path = cache / f"{ic.cache_key(sc)}.npz"
    cache.mkdir(parents=True)
    path.write_bytes(b"PK\x03\x04 truncated")
    t1, p1 = api.ideal_run(sc)
    assert np.array_equal(p1, p0) and np.array_equal(t1, t0)
    assert ic._read(path) is not None  # rewritten whole
    assert not list(cache.glob("*.tmp"))  # no temporary file left behind


def test_entry_is_shared_with_other_processes(cache: Path) -> None:
    """A child process (as in ``compare --jobs`` or a sweep worker) reads the entry the
    parent wrote; of concurrent children missing one key exactly one flies the run (the
    others wait on its lock and read its entry), leaving one readable entry."""
    sc = _sc(nodes=3)
    _t, p0 = api.ideal_run(sc)
    code = (
        "import sys, numpy as np\n"
        "import sigma_des.api as api\n"
        "from sigma_des import Scenario\n"
        "def boom(sc): raise SystemExit(3)\n"
        "sc = Scenario(nodes=3, hosts=1, duration=0.3, warmup=0.1, dynamics='pointmass')\n"
        "if sys.argv[1] == 'read': api.fly_ideal = boom\n"
        "real = api.fly_ideal\n"
        "def counted(sc):\n"
        "    open(sys.argv[2] + '.flew', 'w').close()\n"
        "    return real(sc)\n"
        "if sys.argv[1] == 'write': api.fly_ideal = counted\n"
        "t, p = api.ideal_run(sc)\n"
        "np.save(sys.argv[2], p)\n"
    )
    env = {**os.environ, ic.ENV_VAR: str(cache.parent)}
    out = cache.parent / "child.npy"
    r = subprocess.run([sys.executable, "-c", code, "read", str(out)], env=env, timeout=120)
    assert r.returncode == 0
    assert np.load(out).tobytes() == p0.tobytes()
    # concurrent writers of one (fresh) key
    for f in cache.glob("*.npz"):
        f.unlink()
    procs = [subprocess.Popen([sys.executable, "-c", code, "write", str(out) + str(i)],
                              env=env) for i in range(3)]
    assert [p.wait(timeout=120) for p in procs] == [0, 0, 0]
    entries = list(cache.glob("*.npz"))
    assert len(entries) == 1 and not list(cache.glob("*.tmp"))
    assert len(list(cache.parent.glob("*.flew"))) == 1
    assert all(np.load(str(out) + f"{i}.npy").tobytes() == p0.tobytes() for i in range(3))
    hit = ic._read(entries[0])
    assert hit is not None and hit[1].tobytes() == p0.tobytes()


def test_entry_rows_read_the_stored_bytes_a_block_at_a_time(
    cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    sc = _sc(duration=1.0)
    t0, p0 = api.ideal_run(sc)  # miss: stores the entry
    monkeypatch.setattr(api, "fly_ideal", None)  # a hit must not fly
    t1, rows = ic.cached_rows(sc, api.fly_ideal)
    assert isinstance(rows, ic.EntryRows)
    assert rows.shape == p0.shape and len(rows) == 31 and t1.tobytes() == t0.tobytes()
    for sl in (slice(0, 7), slice(7, 31), slice(29, 99), slice(40, 50), slice(None)):
        assert rows[sl].tobytes() == p0[sl].tobytes(), sl
    rows.close()


def test_entry_rows_of_a_bad_entry_are_a_miss(cache: Path) -> None:
    sc = _sc()
    path = cache / f"{ic.cache_key(sc)}.npz"
    path.parent.mkdir(parents=True)
    t, pos = api.fly_ideal(sc)
    np.savez_compressed(path, t=t, pos=pos)  # not stored in place: read whole instead
    with pytest.raises(ValueError, match="compressed"):
        ic.EntryRows(path)
    t1, p1 = ic.cached_rows(sc, api.fly_ideal)
    assert isinstance(p1, np.ndarray) and p1.tobytes() == pos.tobytes()
    path.write_bytes(b"not a zip")
    assert isinstance(ic.cached_rows(sc, api.fly_ideal)[1], np.ndarray)  # recomputed
    assert isinstance(ic.cached_rows(sc, api.fly_ideal)[1], ic.EntryRows)  # rewritten


def test_cache_off_gives_the_arrays(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ic.ENV_VAR, "off")
    sc = _sc()
    t, p = ic.cached_rows(sc, api.fly_ideal)
    assert isinstance(p, np.ndarray) and p.tobytes() == api.fly_ideal(sc)[1].tobytes()
