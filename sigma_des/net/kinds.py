"""The one declaration of message kinds, which every other module imports.

A message's kind is part of the key of its random draws (with subject, index and
attempt), so the numbers are part of the model: changing them changes results.
The compiled core uses the same values as plain integers (numba folds them as
constants).
"""

from __future__ import annotations

from enum import IntEnum

__all__ = ["ACK", "COMMAND", "KIND_NAMES", "REPUBLISH", "REREQUEST", "RETRY_SLOTS", "STATE",
           "TRIGGER", "Kind", "rerequest_index"]


class Kind(IntEnum):
    """What a message carries."""

    TRIGGER = 1  #: server → nodes: compute frame k
    STATE = 2  #: node → server: the state of frame k
    COMMAND = 3  #: server → node: a behaviour command
    REREQUEST = 4  #: server → node: Lock-Step asks again for a missing state
    REPUBLISH = 5  #: node → server: the answer to a re-request


TRIGGER, STATE, COMMAND, REREQUEST, REPUBLISH = (int(k) for k in Kind)
#: lower-case names, as used in configuration keys and output tables
KIND_NAMES: dict[int, str] = {int(k): k.name.lower() for k in Kind}
#: added to a message kind for its PUBACK's draws
ACK = 16
#: Re-request retries of one frame keyed apart (later retries share the last index).
RETRY_SLOTS = 64


def rerequest_index(frame: int, retry: int) -> int:
    """The index of Lock-Step re-request ``retry`` of ``frame`` and of its republished
    answer (part of their draws' key): ``frame * 64 + min(retry, 63)``."""
    return frame * RETRY_SLOTS + min(retry, RETRY_SLOTS - 1)
