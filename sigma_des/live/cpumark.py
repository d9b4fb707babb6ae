"""A CPU mark taken at a set time by a helper process, off the server's loop thread.

The metrics window opens at the method's warmup, inside the run. A mark there on the
server's loop (psutil and schedstat reads of every process and thread, about 2 ms)
stalls the loop just as the window opens: the trigger due then leaves late, and
Lock-Step's grid restarts at that late trigger for the rest of the run (the DES has no
such stall). :class:`MarkAhead` hands the mark to a child process started before the
run (its interpreter and imports, ~0.15 s of CPU, before the run's idle window): it
sleeps until the given ``time.monotonic()`` (one clock for every process on one
machine) and reads the same figures (:meth:`sigma_des.live.cpu.CpuMeter.mark`), costing
the run a core for those milliseconds instead of its loop.

``python -m sigma_des.live.cpumark`` prints ``ready``, reads one JSON request on stdin
(``procs``: name -> pid; ``at``: monotonic seconds) and prints the mark as one JSON line.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import threading
import time
from typing import Any

from sigma_des.live.broker import child_setup

__all__ = ["MarkAhead", "Taken", "main"]

#: One mark: (wall, machine busy CPU, CPU per process), run-queue wait per process,
#: thread times per process (:meth:`~sigma_des.live.cpu.CpuMeter.mark`).
Taken = tuple[tuple[float, float, dict[str, float]], dict[str, float],
              dict[str, tuple[float, ...]]]


class MarkAhead:
    """A mark of the processes ``procs`` by a child, started (and its imports done)
    before the run, so that neither costs the run anything; :meth:`arm` says when.

    Args:
        procs: name -> pid of the processes to read.
        ready_s: how long the child may take to start (s).
    """

    def __init__(self, procs: dict[str, int], ready_s: float = 30.0) -> None:
        self.procs = dict(procs)
        self.at = math.inf
        self.proc = subprocess.Popen(  # dies with us, as every child of a live run
            [sys.executable, "-m", "sigma_des.live.cpumark"], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=child_setup)
        out = self.proc.stdout
        assert out is not None
        self._first = [""]
        self._reader = threading.Thread(
            target=lambda: self._first.__setitem__(0, out.readline()), daemon=True)
        self._reader.start()  # a bounded wait for its first line
        self._reader.join(ready_s)
        self.ready = self._first[0].strip() == "ready"

    def arm(self, at: float) -> None:
        """Take the mark at ``time.monotonic()`` time ``at``."""
        self.at = at
        assert self.proc.stdin is not None
        try:
            self.proc.stdin.write(json.dumps({"procs": self.procs, "at": at}) + "\n")
            self.proc.stdin.close()
        except OSError:  # the child is gone: result() says so
            pass

    def result(self, timeout: float = 10.0) -> Taken | str:
        """The mark, or why there is none (the child failed or did not answer within
        ``timeout`` seconds after the mark was due: it is killed)."""
        wait = max(0.0, self.at - time.monotonic()) + timeout
        try:  # its answer is one short line: the pipe holds it until read
            self.proc.wait(timeout=wait)
        except subprocess.TimeoutExpired:
            self.cancel()
            return f"no answer within {timeout:g} s of its time"
        assert self.proc.stdout is not None and self.proc.stderr is not None
        self._reader.join(5.0)  # a child slow to start: its first line may be the mark
        first = self._first[0] if self._first[0].strip() != "ready" else ""
        out, err = first + self.proc.stdout.read(), self.proc.stderr.read()
        self.proc.stdout.close()
        self.proc.stderr.close()
        if self.proc.returncode != 0 or not out.strip():
            return f"exit {self.proc.returncode}: {err.strip()[-200:]}"
        d = json.loads(out)
        mark = (_f(d["wall"]), _f(d["busy"]), {k: _f(v) for k, v in d["cpu"].items()})
        threads = {k: tuple(_f(x) for x in v) for k, v in d["threads"].items()}
        return mark, {k: _f(v) for k, v in d["runq"].items()}, threads

    def cancel(self) -> None:
        """Stop the child if it is still waiting (the run ended before the mark)."""
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        for f in (self.proc.stdout, self.proc.stderr):
            if f is not None and not f.closed:
                f.close()


def _nan_safe(x: float) -> float | None:
    return None if x != x else x  # JSON has no NaN: null, read back as NaN


def _f(x: float | None) -> float:
    return math.nan if x is None else float(x)


def main() -> int:
    """The child: read the request, wait for its time, mark, print it."""
    from sigma_des.live.cpu import CpuMeter

    print("ready", flush=True)
    req: dict[str, Any] = json.loads(sys.stdin.readline())
    meter = CpuMeter({str(k): int(v) for k, v in req["procs"].items()})
    time.sleep(max(0.0, float(req["at"]) - time.monotonic()))
    meter.mark("m")
    wall, busy, cpu = meter.marks["m"]
    print(json.dumps({"wall": wall, "busy": busy,
                      "cpu": {k: _nan_safe(v) for k, v in cpu.items()},
                      "runq": {k: _nan_safe(v) for k, v in meter.runq["m"].items()},
                      "threads": {k: [_nan_safe(x) for x in v]
                                  for k, v in meter.threads["m"].items()}}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
