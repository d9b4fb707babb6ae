"""`live --scheduler` to something that is not a Dask scheduler (a silent listener, an
HTTP server) or to one without workers: one line naming --scheduler, exit 2, within
seconds, and no empty --out folder left (nor after a sweep refused before its run)."""

from __future__ import annotations

import http.server
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from sigma_des.cli import main
from sigma_des.errors import ConfigError
from sigma_des.live.broker import child_setup, free_port, wait_port
from sigma_des.live.cluster import probe
from tests.live.live_helpers import LIVE_SETS, needs_mosquitto

SETS = [a for s in LIVE_SETS for a in ("--set", s)]


@pytest.fixture
def silent() -> Iterator[str]:
    """A TCP listener that accepts (in its backlog) and never says a word."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(4)
    try:
        yield f"tcp://127.0.0.1:{s.getsockname()[1]}"
    finally:
        s.close()


@pytest.fixture
def http_400() -> Iterator[str]:
    """A server that answers every connection at once with an HTTP 400."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(4)
    s.settimeout(0.2)
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                c, _ = s.accept()
            except OSError:
                continue
            c.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
            c.close()

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        yield f"tcp://127.0.0.1:{s.getsockname()[1]}"
    finally:
        stop.set()
        t.join(5)
        s.close()


@pytest.fixture
def http_server() -> Iterator[str]:
    """A real HTTP server (it waits for a request)."""
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    t = threading.Thread(target=srv.serve_forever, daemon=True)
    t.start()
    try:
        yield f"tcp://127.0.0.1:{srv.server_address[1]}"
    finally:
        srv.shutdown()
        srv.server_close()


def test_the_probe_names_what_answered(silent: str, http_400: str) -> None:
    with pytest.raises(ConfigError, match=r"is not a Dask scheduler \(sent nothing within 0.5 s"):
        probe(silent, 0.5)
    with pytest.raises(ConfigError, match=r"is not a Dask scheduler \(an HTTP server\)"):
        probe(http_400, 0.5)
    with pytest.raises(ConfigError, match="no Dask scheduler answers at"):
        probe(f"tcp://127.0.0.1:{free_port()}", 0.5)
    probe("tls://127.0.0.1:1", 0.5)  # TLS is not probed (the client speaks first)


def _refused(address: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> str:
    out = tmp_path / "new" / "out"
    rc = main(["live", *SETS, "--methods", "none", "--scheduler", address, "--out", str(out),
               "--no-progress", "--no-plots"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.count("\n") == 0 and "Traceback" not in err, err
    assert err.startswith("sigma-des: error: --scheduler: ")
    assert not (tmp_path / "new").exists()  # no empty --out folder (nor its new parent)
    return err


@needs_mosquitto
@pytest.mark.parametrize("server", ["silent", "http_400", "http_server"])
def test_live_to_a_non_scheduler_exits_2_naming_the_option(
        server: str, request: pytest.FixtureRequest, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("distributed")
    address = request.getfixturevalue(server)
    err = _refused(address, tmp_path, capsys)
    assert f"{address} is not a Dask scheduler" in err
    assert ("an HTTP server" in err) == (server == "http_400")


@needs_mosquitto
def test_a_scheduler_without_workers_leaves_no_out_folder(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("distributed")
    port = free_port()
    p = subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1",
                          "--port", str(port), "--no-dashboard"], stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL, preexec_fn=child_setup)
    try:
        assert wait_port("127.0.0.1", port, 60.0)
        err = _refused(f"tcp://127.0.0.1:{port}", tmp_path, capsys)
        assert "the scheduler has no workers" in err
    finally:
        p.terminate()
        p.wait(10)


def test_a_refused_sweep_leaves_no_out_folder(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "a" / "b"
    assert main(["sweep", "--grid", "seed=1,2", "--out", str(out)]) == 2
    assert "seed: cannot be a grid axis" in capsys.readouterr().err
    assert not (tmp_path / "a").exists()
    (tmp_path / "kept").mkdir()  # a folder that was there before stays, even if empty
    assert main(["sweep", "--grid", "seed=1,2", "--out", str(tmp_path / "kept")]) == 2
    assert (tmp_path / "kept").is_dir()
