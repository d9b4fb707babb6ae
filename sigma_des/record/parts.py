"""``compare --record``: one part file per method, joined into the recording at the end.

Every method's run records into its own hidden part file next to the final one
(``.x.mcap.<run>.<method>.part``, ``<run>`` unique to this run; worker processes can
write them at once); when the runs
end, the parts of the methods that finished are joined into a hidden temporary file
that is fsynced and renamed to ``x.mcap``. So the final name only ever holds a
complete recording, whatever happens: a full disk, Ctrl-C or SIGKILL during the runs
or the join leaves the previous ``x.mcap`` (if any) untouched, and every error path
removes the part and temporary files (a SIGKILL can leave hidden ones, which the
next run of the same recording removes).

A run holds a lock on the recording (``.x.mcap.lock``, :class:`~sigma_des.lock.
OutputLock`) from its start to the join: a second run recording to the same file at
the same time is refused at once, naming ``--record``.
"""

from __future__ import annotations

import contextlib
import glob
import os
import secrets
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

from sigma_des.errors import ConfigError
from sigma_des.lock import OutputLock

__all__ = ["RecordParts"]


class RecordParts:
    """The part files of one ``--record`` path and their join.

    Args:
        record: the final ``.mcap`` file.
        methods: the methods that will be recorded.
        key: the option named in errors.
    """

    def __init__(self, record: str | Path, methods: Sequence[str], key: str = "--record") -> None:
        self.out = Path(record)
        self.key = key
        self._lock = OutputLock(self.out.with_name(f".{self.out.name}.lock"), key,
                                str(self.out))
        for stale in self.out.parent.glob(f".{glob.escape(self.out.name)}.*.part"):
            with contextlib.suppress(OSError):  # a killed run's: nobody else writes here
                stale.unlink()
        run = f"{os.getpid()}-{secrets.token_hex(3)}"
        self.paths = {m: self.out.with_name(f".{self.out.name}.{run}.{m}.part")
                      for m in methods}
        self._tmp = self.out.with_name(f".{self.out.name}.{run}.join.part")

    def get(self, method: str) -> Path:
        """The part file of ``method``."""
        return self.paths[method]

    def remove(self) -> None:
        """Delete every part and temporary file (missing ones are fine); release the lock."""
        for p in (*self.paths.values(), self._tmp):
            with contextlib.suppress(OSError):
                p.unlink()
        self._lock.release()

    def error(self, e: OSError) -> ConfigError:
        """The one-line error of a failed write (after removing every part)."""
        self.remove()
        return ConfigError(self.key, f"cannot write {self.out}: {e.strerror or e}")

    @contextlib.contextmanager
    def cleaned(self) -> Iterator[RecordParts]:
        """A block whose exceptions remove every part (an ``OSError`` becomes a
        :class:`~sigma_des.errors.ConfigError` naming the option)."""
        try:
            yield self
        except OSError as e:
            raise self.error(e) from None
        except BaseException:
            self.remove()
            raise

    def join(self, methods: Iterable[str], scenario: dict[str, Any], spec: Any) -> Path:
        """Join the parts of ``methods`` (in that order) into the final file.

        One method: its part is renamed into place. Several: they are merged into a
        temporary file (``log_time`` order, messages copied as stored), fsynced and
        renamed. Every part is removed afterwards.

        Args:
            methods: the finished methods.
            scenario: the resolved scenario (plain dict) stored in the file.
            spec: the record settings (``sc.record``).

        Raises:
            ConfigError: a write failed (disk full…); nothing is left under the final
                name that was not there before.
        """
        from sigma_des.record.writer import Recorder

        ms = list(methods)
        with self.cleaned():
            if len(ms) == 1:
                os.replace(self.paths[ms[0]], self.out)
            else:
                with Recorder(self._tmp, scenario=scenario, mode=spec.mode,
                              deadband_pos=spec.deadband_pos, deadband_vel=spec.deadband_vel,
                              deadband_att=spec.deadband_att,
                              keyframe_every=spec.keyframe_every) as rec:
                    for m in ms:
                        rec.copy_from(self.paths[m])
                os.replace(self._tmp, self.out)
            self.remove()
        return self.out
