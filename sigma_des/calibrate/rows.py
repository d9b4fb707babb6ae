"""Malformed rows of a message table: counted, reported, refused above a small share.

A hand-edited or damaged ``messages.csv.gz`` can hold rows a fit must not read: an
unknown method or kind (a lost comma turns ``bides,state`` into ``bidesstate`` and
shifts every field), a field that is not a number, or a field its kind needs left
empty. :func:`drop_malformed` removes them, says how many (and the first one's line)
on stderr, and refuses the table when more than :data:`MAX_MALFORMED_SHARE` of its
rows are malformed: a fit over such a table would change without a word.
"""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd

from sigma_des.config import ALL_METHODS
from sigma_des.errors import ConfigError

__all__ = ["KIND_FIELDS", "MAX_MALFORMED_SHARE", "drop_malformed"]

#: The fields each row kind must hold (besides ``method`` and ``kind``).
KIND_FIELDS: dict[str, tuple[str, ...]] = {
    "trigger_sent": ("host", "node", "frame", "t_send"),
    "trigger": ("host", "node", "frame", "t_send", "t_recv"),
    "state_pub": ("host", "node", "frame", "t_send", "t_trig", "cost"),
    "state": ("host", "node", "frame", "t_send", "t_recv", "t_trig"),
    "command": ("host", "node", "frame", "t_send", "t_recv"),
}
#: The largest share of malformed rows a table may hold and still be read (1 %).
MAX_MALFORMED_SHARE = 0.01
_NUMERIC = ("host", "node", "frame", "t_send", "t_recv", "t_trig", "cost")


def _reasons(df: pd.DataFrame) -> pd.Series:
    """Per row, why it is malformed ("" when it is not)."""
    why = pd.Series("", index=df.index, dtype=object)
    for col in (c for c in _NUMERIC if c in df.columns):
        raw = df[col]
        num = pd.to_numeric(raw, errors="coerce")
        bad = raw.notna() & (num.isna() | ~np.isfinite(num.astype(float)))
        why[bad & (why == "")] = f"{col} is not a finite number"
        df[col] = num
    for kind, fields in KIND_FIELDS.items():
        rows = df["kind"] == kind
        for col in (c for c in fields if c in df.columns):
            why[rows & df[col].isna() & (why == "")] = f"a {kind} row without {col}"
    if "republish" in df.columns:
        flag = df["republish"].astype(str)
        why[~flag.isin(["True", "False"]) & (why == "")] = "republish is not True or False"
        df["republish"] = flag == "True"
    kinds = df["kind"].astype(str)
    why[~kinds.isin(list(KIND_FIELDS)) & (why == "")] = "unknown kind " + kinds
    methods = df["method"].astype(str)
    why[~methods.isin(ALL_METHODS)] = "unknown method " + methods  # first: it shifts the rest
    return why


def drop_malformed(df: pd.DataFrame, path: str) -> pd.DataFrame:
    """``df`` without its malformed rows, reported on stderr.

    Args:
        df: a message table as read from CSV (``method`` and ``kind`` columns present).
        path: its file, named in the report.

    Returns:
        The well-formed rows (numeric columns as numbers); ``attrs["malformed"]`` holds
        the number of rows dropped.

    Raises:
        ConfigError: (naming ``path``) more than 1 % of the rows are malformed.
    """
    why = _reasons(df)
    bad = why != ""
    n_bad, n = int(bad.sum()), len(df)
    if n_bad:
        first = int(np.flatnonzero(bad.to_numpy())[0])
        detail = f"{n_bad} of {n} rows are malformed (first: line {first + 2}, {why.iloc[first]})"
        if n_bad > MAX_MALFORMED_SHARE * n:
            raise ConfigError(path, f"{detail}: more than {MAX_MALFORMED_SHARE:.0%} of the "
                                    "table; expected the rows `sigma-des live --out` writes")
        print(f"sigma-des: warning: {path}: {detail}; dropped them", file=sys.stderr)
        df = df[~bad].reset_index(drop=True)
        for col in ("host", "node", "frame"):
            df[col] = df[col].astype(np.int64)
    df.attrs["malformed"] = n_bad
    return df
