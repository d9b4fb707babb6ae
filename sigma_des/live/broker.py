"""A private Mosquitto broker per live run: config, credentials, start, stop.

:class:`Broker` writes a generated ``mosquitto.conf`` (loopback listener on a free
port, ``allow_anonymous false``, a password file with one per-run user, no
persistence, ``set_tcp_nodelay true``) into a temporary directory, starts
``mosquitto -c`` and waits until the port accepts connections. It is a context
manager: the process is terminated (then killed) on exit, whatever happened.
The password file uses Mosquitto 2's PBKDF2-SHA512 format (``$7$``), so
``mosquitto_passwd`` is not needed.
"""

from __future__ import annotations

import base64
import ctypes
import hashlib
import os
import pwd
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

from sigma_des.errors import ConfigError

__all__ = [
    "Broker",
    "BrokerAddress",
    "INSTALL_HINT",
    "Janitor",
    "child_setup",
    "find_mosquitto",
    "free_port",
    "parse_broker",
    "password_line",
    "reap",
    "wait_port",
]

INSTALL_HINT = (
    "mosquitto not found; install the OS package, e.g. `sudo apt-get install mosquitto` "
    "(Debian/Ubuntu), `brew install mosquitto` (macOS) or `dnf install mosquitto`, "
    "or pass --broker HOST:PORT of a running broker"
)
_SEARCH = ("/usr/sbin/mosquitto", "/usr/local/sbin/mosquitto", "/opt/homebrew/sbin/mosquitto")


@dataclass(frozen=True)
class BrokerAddress:
    """Where and as whom the live clients connect.

    Attributes:
        host: broker host (a loopback address for a broker we start).
        port: TCP port.
        username: MQTT user name ('' for none).
        password: MQTT password ('' for none).
        tls_ca: PEM text of the CA certificate(s) the broker's certificate must chain to
            ('' : plain TCP). The text, not a path: hosts on other machines get it too.
    """

    host: str
    port: int
    username: str = ""
    password: str = ""
    tls_ca: str = ""


def child_setup() -> None:
    """``preexec_fn`` of our children: a session of their own (the terminal's Ctrl-C
    reaches only us; we stop them) and, on Linux, SIGTERM when we die, so nothing
    outlives a killed ``sigma-des``."""
    os.setsid()
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def reap(p: subprocess.Popen[bytes]) -> None:
    """Terminate ``p`` (then kill it): at most 6 s."""
    if p.poll() is None:
        p.terminate()
        try:
            p.wait(timeout=3)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(timeout=3)


#: The janitor: reads folder names, one a line, until its stdin closes (our exit, however
#: we die: even SIGKILL closes the pipe), then removes them (retrying while a dying child
#: may still be writing). It ignores the terminal's signals: it must outlive us.
_JANITOR = """\
import os, shutil, signal, sys, time
for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
    signal.signal(s, signal.SIG_IGN)
paths = [line.rstrip("\\n") for line in sys.stdin]
for _ in range(50):
    for p in paths:
        shutil.rmtree(p, ignore_errors=True)
    if not any(os.path.exists(p) for p in paths):
        break
    time.sleep(0.1)
"""


class Janitor:
    """A small process that removes our temporary folders when we exit, however we exit.

    Clean-up code does not run on SIGKILL; the janitor does, because the pipe we
    hold to it closes when we die. It covers the run's folders (host configs, logs,
    rows) and the broker's (its password file). Used as a context manager; on a
    normal exit it is told to finish and waited for (bounded).
    """

    def __init__(self) -> None:
        self.proc = subprocess.Popen([sys.executable, "-c", _JANITOR], stdin=subprocess.PIPE,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                     start_new_session=True)

    def watch(self, path: str | Path) -> None:
        """Remove ``path`` (a folder) when we exit."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(f"{path}\n".encode())
        self.proc.stdin.flush()

    def close(self) -> None:
        """Let the janitor remove what it watches now and wait for it (<= 6 s)."""
        if self.proc.stdin is not None and not self.proc.stdin.closed:
            self.proc.stdin.close()
        try:
            self.proc.wait(timeout=6)
        except subprocess.TimeoutExpired:
            self.proc.kill()

    def __enter__(self) -> Janitor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def find_mosquitto() -> str | None:
    """Path of the ``mosquitto`` executable (PATH, then the usual sbin folders)."""
    found = shutil.which("mosquitto")
    if found:
        return found
    for p in _SEARCH:
        if os.access(p, os.X_OK):
            return p
    return None


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that was free on ``host`` a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def wait_port(host: str, port: int, timeout: float) -> bool:
    """True once ``host:port`` accepts a TCP connection (polled, bounded by ``timeout``)."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            with socket.create_connection((host, port), timeout=0.2):
                return True
        except OSError:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)


def parse_broker(text: str) -> tuple[str, int]:
    """``HOST:PORT`` -> (host, port).

    Raises:
        ConfigError: naming ``--broker`` if the text is not ``HOST:PORT`` with a port in 1..65535.
    """
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ConfigError("--broker", f"must be HOST:PORT with a port in 1..65535, got {text!r}")
    return host, int(port)


def password_line(username: str, password: str, salt: bytes | None = None) -> str:
    """One Mosquitto 2 password-file line: ``user:$7$101$<salt b64>$<PBKDF2-SHA512 b64>``."""
    salt = secrets.token_bytes(12) if salt is None else salt
    iterations = 101
    digest = hashlib.pbkdf2_hmac("sha512", password.encode(), salt, iterations)
    b64 = base64.b64encode
    return f"{username}:$7${iterations}${b64(salt).decode()}${b64(digest).decode()}"


class Broker:
    """A Mosquitto process of our own on a loopback port (a context manager).

    Args:
        port: TCP port (default: a free one).
        max_inflight: ``max_inflight_messages`` per client (QoS 1 window; 0 = unlimited).
        executable: path of ``mosquitto`` (default: :func:`find_mosquitto`).
        janitor: removes the broker's folder (its password file) even if we are killed.
        users: more users (name: password) besides the per-run one, e.g. observers.
        acl: the text of a Mosquitto ``acl_file`` (``user`` and ``topic`` lines; see
            docs/howto/live.md); None: no ACL (every user may use every topic).

    Raises:
        ConfigError: ``mosquitto`` missing (the message says how to install it), or
            the broker did not come up (e.g. ``--broker-port`` in use).
    """

    def __init__(self, port: int | None = None, max_inflight: int = 0,
                 executable: str | None = None, janitor: Janitor | None = None,
                 users: dict[str, str] | None = None, acl: str | None = None) -> None:
        exe = executable or find_mosquitto()
        if exe is None:
            raise ConfigError("mosquitto", INSTALL_HINT)
        self.exe = exe
        self.port = port if port is not None else free_port()
        self.max_inflight = max_inflight
        self.username = "sd-" + secrets.token_hex(4)
        self.password = secrets.token_urlsafe(18)
        self.proc: subprocess.Popen[bytes] | None = None
        self._dir: tempfile.TemporaryDirectory[str] | None = None
        self.janitor = janitor
        self.users = dict(users or {})
        self.acl = acl

    @property
    def address(self) -> BrokerAddress:
        """Where clients connect, with the per-run credentials."""
        return BrokerAddress("127.0.0.1", self.port, self.username, self.password)

    def config_text(self, passwd_path: str, log_path: str, acl_path: str | None = None) -> str:
        """The generated ``mosquitto.conf``."""
        acl = [f"acl_file {acl_path}"] if acl_path else []
        return "\n".join(
            [
                # run as whoever starts it: as root, mosquitto would otherwise drop to
                # the 'mosquitto' user, which cannot read our 0600 password file
                f"user {pwd.getpwuid(os.geteuid()).pw_name}",
                f"listener {self.port} 127.0.0.1",
                "allow_anonymous false",
                f"password_file {passwd_path}",
                "persistence false",
                "set_tcp_nodelay true",
                f"max_inflight_messages {self.max_inflight}",
                "max_queued_messages 100000",
                f"log_dest file {log_path}",
                "log_type error",
                "log_type warning",
                *acl,
                "",
            ]
        )

    def start(self) -> BrokerAddress:
        """Write the config, start Mosquitto and wait (<= 5 s) for its port."""
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
            try:
                probe.bind(("127.0.0.1", self.port))
            except OSError as e:
                raise ConfigError("--broker-port",
                                  f"127.0.0.1:{self.port} is in use ({e.strerror})") from None
        self._dir = tempfile.TemporaryDirectory(prefix="sigma-des-mqtt-")
        d = Path(self._dir.name)
        if self.janitor is not None:
            self.janitor.watch(d)
        passwd = d / "passwd"
        users = {self.username: self.password, **self.users}
        passwd.write_text("".join(password_line(u, p) + "\n" for u, p in users.items()))
        passwd.chmod(0o600)
        acl = None
        if self.acl is not None:
            acl = d / "acl"
            acl.write_text(self.acl)
        conf = d / "mosquitto.conf"
        conf.write_text(self.config_text(str(passwd), str(d / "mosquitto.log"),
                                         str(acl) if acl else None))
        self.proc = subprocess.Popen(
            [self.exe, "-c", str(conf)],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            preexec_fn=child_setup,  # Ctrl-C reaches us only; we stop the broker ourselves
        )
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raw = self.proc.stderr.read() if self.proc.stderr else b""
                err = raw.decode(errors="replace")
                log = d / "mosquitto.log"
                err += log.read_text(errors="replace") if log.exists() else ""
                self.stop()
                raise ConfigError(
                    "--broker-port",
                    f"mosquitto exited at start on 127.0.0.1:{self.port} (port in use?): "
                    f"{err.strip()[-300:]}",
                )
            if wait_port("127.0.0.1", self.port, 0.05):
                return self.address
        self.stop()
        raise ConfigError("--broker-port", f"mosquitto did not listen on port {self.port} in 5 s")

    def kill(self) -> None:
        """Kill the broker at once (fault injection: a broker crash)."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=5)

    def restart(self) -> None:
        """Start the broker again on the same port with the same credentials."""
        assert self._dir is not None
        d = Path(self._dir.name)
        self.proc = subprocess.Popen(
            [self.exe, "-c", str(d / "mosquitto.conf")],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            preexec_fn=child_setup,
        )
        wait_port("127.0.0.1", self.port, 5.0)

    def stop(self) -> None:
        """Terminate (then kill) the process and remove its files; safe to call twice."""
        p = self.proc
        if p is not None:
            reap(p)
        if p is not None and p.stderr is not None:
            p.stderr.close()
        self.proc = None
        if self._dir is not None:
            self._dir.cleanup()
            self._dir = None

    def __enter__(self) -> BrokerAddress:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
