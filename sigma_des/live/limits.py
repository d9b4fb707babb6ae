"""What a live run may ask of this machine and of live mode, checked before anything starts.

Sizes (host processes per core, memory) and the scenario features live mode runs; each
refusal names the key, as the scenario's own validation does.
"""

from __future__ import annotations

import os

from sigma_des.config import METHODS, Scenario
from sigma_des.errors import ConfigError

__all__ = ["HOSTS_PER_CORE", "check_live", "check_size", "estimate_live_bytes"]


#: Resident memory of one host process (Python, NumPy, numba, paho; measured ~190 MB)
HOST_BYTES = 200 * 2**20
#: ... and of the server process before its per-run arrays (measured ~235 MB)
SERVER_BYTES = 256 * 2**20
#: One message row as the processes keep it (a tuple of 9 Python numbers), bytes
ROW_BYTES = 300
#: Host processes per CPU core beyond which the hosts cannot keep real time
HOSTS_PER_CORE = 8


def estimate_live_bytes(sc: Scenario) -> int:
    """Memory a live run of ``sc`` takes: every process's base, the server's arrays (as
    ``compare`` estimates them) and the message rows (a state is a row on its host and
    on the server; a trigger one per host; a command one)."""
    from sigma_des.budget import estimate_bytes

    frames = sc.duration * sc.f_trig
    cmds = sc.duration * sc.f_align / sc.commands.every * sc.nodes if sc.commands.enabled else 0
    rows = 2 * frames * sc.nodes + frames * (sc.hosts + 1) + cmds
    return int(SERVER_BYTES + sc.hosts * HOST_BYTES + estimate_bytes(sc, 1) + rows * ROW_BYTES)


def check_size(sc: Scenario, force: bool = False, remote_hosts: bool = False) -> int:
    """Refuse, before anything is spawned, a live run this machine cannot hold.

    With ``remote_hosts`` (the hosts run on a Dask cluster) the host processes' own memory
    is not this machine's (their rows, fetched at the end, are).

    Returns:
        The memory estimate (bytes).

    Raises:
        ConfigError: (key ``hosts``) more host processes than ``HOSTS_PER_CORE`` per CPU
            core, or (key ``memory``, naming nodes, hosts and duration) more memory than
            is available; not with ``force``.
    """
    from sigma_des.budget import available_bytes
    from sigma_des.guard import require_memory

    need = estimate_live_bytes(sc)
    if remote_hosts:
        need -= sc.hosts * HOST_BYTES
    if force:
        return need
    cores = os.cpu_count() or 1
    if not remote_hosts and sc.hosts > HOSTS_PER_CORE * cores:
        raise ConfigError("hosts", f"{sc.hosts} host processes (nodes={sc.nodes}) would be "
                          f"spawned, but {cores} CPU cores keep at most "
                          f"{HOSTS_PER_CORE * cores} in real time; lower nodes or hosts, "
                          "or pass --force")
    return require_memory(need, available_bytes(),
                          f"a live run of nodes={sc.nodes} on hosts={sc.hosts} over "
                          f"duration={sc.duration:g} s", "lower nodes, hosts or duration")


def check_live(sc: Scenario) -> None:
    """Reject what live mode cannot do, naming the key."""
    for m in sc.methods:
        if m not in METHODS:
            raise ConfigError("methods", f"live mode runs {', '.join(METHODS)}, not {m!r}")
    if getattr(sc.net, "middleware", "mqtt") != "mqtt":
        raise ConfigError("net.middleware", "live mode runs over MQTT (Mosquitto): must be "
                          f"'mqtt', got {sc.net.middleware!r}")
    for i, f in enumerate(sc.faults):
        if f.kind not in ("crash", "slow"):
            raise ConfigError(f"faults[{i}].kind", f"live mode runs 'crash' and 'slow' faults, "
                              f"not {f.kind!r}")
    if sc.dynamics.startswith("jsbsim:"):
        raise ConfigError("dynamics", "live mode runs the built-in models (pointmass, "
                          "quadrotor, fixedwing), not JSBSim")
