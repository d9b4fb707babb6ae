"""``--broker`` over TLS (``--tls-ca``): a Mosquitto TLS listener on 127.0.0.1 with a
certificate signed by a CA made here (openssl); a run with that CA works, one with
another CA is refused (exit 2, one line naming --broker)."""

from __future__ import annotations

import json
import os
import pwd
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from sigma_des.cli import main
from sigma_des.live.broker import child_setup, find_mosquitto, free_port, password_line, wait_port
from tests.live.live_helpers import LIVE_SETS, needs_mosquitto

pytestmark = [needs_mosquitto,
              pytest.mark.skipif(shutil.which("openssl") is None, reason="needs openssl")]


def _ssl(d: Path, *args: str) -> None:
    subprocess.run(["openssl", *args], cwd=d, check=True, capture_output=True, timeout=60)


def _ca(d: Path, name: str) -> None:
    _ssl(d, "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", f"{name}.key",
         "-out", f"{name}.pem", "-days", "1", "-subj", f"/CN={name}")


@pytest.fixture(scope="module")
def tls_broker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[int, Path]]:
    d = tmp_path_factory.mktemp("tls")
    _ca(d, "ca")
    _ca(d, "other")
    _ssl(d, "req", "-newkey", "rsa:2048", "-nodes", "-keyout", "srv.key", "-out", "srv.csr",
         "-subj", "/CN=127.0.0.1")
    (d / "ext").write_text("subjectAltName=IP:127.0.0.1\n")
    _ssl(d, "x509", "-req", "-in", "srv.csr", "-CA", "ca.pem", "-CAkey", "ca.key",
         "-CAcreateserial", "-out", "srv.pem", "-days", "1", "-extfile", "ext")
    (d / "passwd").write_text(password_line("sim", "s3cret") + "\n")
    (d / "pw").write_text("s3cret\n")
    port = free_port()
    (d / "mosquitto.conf").write_text("\n".join([
        f"user {pwd.getpwuid(os.geteuid()).pw_name}", f"listener {port} 127.0.0.1",
        f"cafile {d / 'ca.pem'}", f"certfile {d / 'srv.pem'}", f"keyfile {d / 'srv.key'}",
        "allow_anonymous false", f"password_file {d / 'passwd'}", "persistence false",
        "set_tcp_nodelay true", "max_inflight_messages 0", ""]))
    exe = find_mosquitto()
    assert exe is not None
    p = subprocess.Popen([exe, "-c", str(d / "mosquitto.conf")], stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL, preexec_fn=child_setup)
    try:
        assert wait_port("127.0.0.1", port, 10.0)
        yield port, d
    finally:
        p.terminate()
        p.wait(timeout=10)


def _args(port: int, d: Path, ca: str) -> list[str]:
    sets = [a for s in LIVE_SETS for a in ("--set", s)]
    return ["live", *sets, "--methods", "none", "--broker", f"127.0.0.1:{port}", "--username",
            "sim", "--password-file", str(d / "pw"), "--tls-ca", str(d / ca), "--no-progress"]


def test_live_run_over_tls(tls_broker: tuple[int, Path], tmp_path: Path) -> None:
    port, d = tls_broker
    assert main([*_args(port, d, "ca.pem"), "--out", str(tmp_path), "--no-plots"]) == 0
    summ = json.loads((tmp_path / "summary.json").read_text())
    assert summ["live"]["none"]["hosts_reported"] == [0, 1]  # the hosts came in over TLS too
    assert summ["methods"]["none"]["snapshot_rate_hz"] > 0


def test_a_certificate_of_another_ca_is_refused(tls_broker: tuple[int, Path],
                                                capsys: pytest.CaptureFixture[str]) -> None:
    port, d = tls_broker
    assert main(_args(port, d, "other.pem")) == 2
    err = capsys.readouterr().err.strip()
    assert "--broker" in err and "CERTIFICATE_VERIFY_FAILED" in err and "\n" not in err
    assert main(_args(port, d, "srv.key")) == 2  # not a certificate at all
    assert "--tls-ca" in capsys.readouterr().err
