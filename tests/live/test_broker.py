"""Our own Mosquitto: per-run credentials enforced, anonymous refused, clean stop."""

from __future__ import annotations

import socket

import pytest

from sigma_des.errors import ConfigError
from sigma_des.live.broker import Broker, BrokerAddress, free_port, parse_broker, wait_port
from sigma_des.live.loop import Client
from tests.live.live_helpers import needs_mosquitto


def _connect(addr: BrokerAddress) -> Client:
    c = Client(addr, "probe", [], lambda t, p: None)
    c.start(timeout=3.0)
    return c


@needs_mosquitto
def test_credentials_are_enforced_and_the_broker_stops() -> None:
    b = Broker()
    with b as addr:
        assert addr.host == "127.0.0.1" and addr.username.startswith("sd-")
        _connect(addr).stop()
        for user, pw in ((addr.username, "wrong"), ("", ""), ("other", addr.password)):
            with pytest.raises(ConnectionError, match="Not authorized|no CONNACK"):
                _connect(BrokerAddress(addr.host, addr.port, user, pw))
    assert b.proc is None
    assert not wait_port("127.0.0.1", addr.port, 0.2)


@needs_mosquitto
def test_port_in_use_is_a_config_error() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        with pytest.raises(ConfigError, match="--broker-port"):
            Broker(port=port).start()


def test_missing_mosquitto_names_the_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("sigma_des.live.broker.find_mosquitto", lambda: None)
    with pytest.raises(ConfigError, match="apt-get install mosquitto"):
        Broker()


def test_parse_broker() -> None:
    assert parse_broker("127.0.0.1:1883") == ("127.0.0.1", 1883)
    for bad in ("localhost", ":1883", "h:0", "h:70000", "h:x"):
        with pytest.raises(ConfigError, match="--broker"):
            parse_broker(bad)
    assert 1 <= free_port() <= 65535
