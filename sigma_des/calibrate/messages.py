"""Calibration's input: a live run's message table read back, checked row by row.

:func:`read_messages` reads ``messages.csv.gz`` of a ``sigma-des live --out`` folder
(written by :mod:`sigma_des.live.messages`, which documents its columns) or the message
rows of an MCAP recording; malformed rows are counted and dropped, or the table refused
(:mod:`sigma_des.calibrate.rows`).
"""

from __future__ import annotations

import zlib
from pathlib import Path

import pandas as pd

from sigma_des.errors import ConfigError
from sigma_des.live.messages import FILE

__all__ = ["read_messages"]


def read_messages(source: Path) -> pd.DataFrame:
    """The message table of a live ``--out`` directory (or its ``messages.csv.gz``), or of
    an MCAP recording (through ``sigma_des.record.read_table``).

    Raises:
        ConfigError: naming the path if it is missing or not a live output.
    """
    if source.suffix == ".mcap":
        try:
            from sigma_des.record import read_table
        except ImportError:
            raise ConfigError(str(source), "reading MCAP needs sigma_des.record") from None
        return read_table(source)
    path = source / FILE if source.is_dir() else source
    if not path.exists():
        raise ConfigError(str(source), f"no {FILE} here: pass a `sigma-des live --out` directory")
    from sigma_des.guard import input_file

    input_file(path, str(path), "live message table (messages.csv.gz)")
    expected = "a gzip-compressed CSV written by `sigma-des live --out`"
    try:
        df = pd.read_csv(path)
    except pd.errors.EmptyDataError:
        raise ConfigError(str(path), f"is empty; expected {expected}") from None
    except (OSError, EOFError, zlib.error, UnicodeDecodeError, pd.errors.ParserError,
            ValueError) as e:
        why = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise ConfigError(str(path), f"not readable as {expected} ({why})") from None
    need = {"method", "kind", "node", "frame", "t_send", "t_recv"}
    if not need <= set(df.columns):
        raise ConfigError(str(path), f"missing columns {sorted(need - set(df.columns))}")
    if df.empty:
        raise ConfigError(str(path), "has a header but no message rows; expected the "
                          "messages of a live run")
    from sigma_des.calibrate.rows import drop_malformed

    df = drop_malformed(df, str(path))
    for col in ("node", "frame", "t_send", "t_recv"):
        if not pd.api.types.is_numeric_dtype(df[col]):
            raise ConfigError(str(path), f"column {col!r} is not numeric")
    return df
