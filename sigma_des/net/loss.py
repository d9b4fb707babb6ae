"""Packet loss on a link: Bernoulli or Gilbert–Elliott bursts (docs/concepts/model.md, "Network").

:class:`LossSpec` is the validated configuration; :class:`LossProcess` decides,
for a packet sent at time ``t`` and keyed by integer ids (e.g. message kind,
entity, frame, attempt), whether it is lost. Every decision is a pure function of
``(stream, link_id, ids, t)``, never of the order in which packets are asked
about, and calls are vectorised (``t`` and the ids broadcast together).

Gilbert–Elliott: a two-state (good/bad) Markov chain over time slots
``s = floor(t / slot)``. The state of slot 0 is drawn from the stationary
distribution, and the transition into slot ``s >= 1`` uses one uniform draw keyed
by ``(link_id, -1, s)``: from good, go bad if ``u < p_gb``; from bad, go good if
``u < p_bg``. The chain is built lazily, in chunks, and cached, so asking about a
late packet first gives the same channel as asking in time order. Within a state
the packet is lost with probability ``loss_good`` or ``loss_bad`` using a draw
keyed by ``(link_id, *ids)`` (the same draw as the Bernoulli model).

Key layout on the stream (``ids`` must be non-negative so they cannot collide
with the negative tags): packet draw ``(link_id, *ids)``; chain draw
``(link_id, -1, s)``; fault-window draw ``(link_id, -2, *ids)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sigma_des.core.rng import Stream
from sigma_des.errors import ConfigError

__all__ = ["LOSS_MODELS", "LossSpec", "LossProcess"]

#: Allowed values of :attr:`LossSpec.model`.
LOSS_MODELS: tuple[str, ...] = ("bernoulli", "gilbert_elliott")

_CHAIN_TAG = -1
_EXTRA_TAG = -2
_MIN_CHUNK = 1 << 16


def _prob(name: str, value: object, *, below_one: bool = False) -> float:
    """``value`` as a float in [0, 1] (or [0, 1) if ``below_one``), else ConfigError."""
    rng = "[0, 1)" if below_one else "[0, 1]"
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(name, f"must be a probability in {rng}, got {value!r}")
    v = float(value)
    if not (0.0 <= v <= 1.0):
        raise ConfigError(name, f"must be a probability in {rng}, got {value!r}")
    if below_one and v == 1.0:
        raise ConfigError(name, f"must be in {rng}: {name} = 1 would lose every packet")
    return v


@dataclass(frozen=True)
class LossSpec:
    """Loss model of a link.

    Attributes:
        model: ``bernoulli`` or ``gilbert_elliott``.
        p: Bernoulli loss probability per packet, in [0, 1).
        p_gb: Gilbert–Elliott good→bad transition probability per slot, [0, 1].
        p_bg: bad→good transition probability per slot, [0, 1].
        loss_good: loss probability of a packet sent in the good state, [0, 1].
        loss_bad: loss probability of a packet sent in the bad state, [0, 1].
        slot: time step of the chain in seconds, > 0.
    """

    model: str = "bernoulli"
    p: float = 0.0
    p_gb: float = 0.0
    p_bg: float = 1.0
    loss_good: float = 0.0
    loss_bad: float = 1.0
    slot: float = 0.001

    def __post_init__(self) -> None:
        if not isinstance(self.model, str) or self.model not in LOSS_MODELS:
            allowed = ", ".join(LOSS_MODELS)
            raise ConfigError("model", f"must be one of {allowed}; got {self.model!r}")
        object.__setattr__(self, "p", _prob("p", self.p, below_one=True))
        for name in ("p_gb", "p_bg", "loss_good", "loss_bad"):
            object.__setattr__(self, name, _prob(name, getattr(self, name)))
        slot = self.slot
        if isinstance(slot, bool) or not isinstance(slot, int | float):
            raise ConfigError("slot", f"must be a time step in seconds > 0, got {slot!r}")
        if not (math.isfinite(slot) and slot > 0.0):
            raise ConfigError("slot", f"must be a time step in seconds > 0 (finite), got {slot!r}")
        object.__setattr__(self, "slot", float(slot))
        if self.model == "gilbert_elliott" and self.expected_loss() >= 1.0:
            name = "loss_good" if self.loss_good == 1.0 else "loss_bad"
            raise ConfigError(
                name,
                "must be < 1: with these transition probabilities the channel would "
                "lose every packet in the long run",
            )

    @property
    def bad_fraction(self) -> float:
        """Stationary probability of the bad state (0 if the chain never moves)."""
        total = self.p_gb + self.p_bg
        return 0.0 if total == 0.0 else self.p_gb / total

    def expected_loss(self) -> float:
        """Long-run fraction of packets lost (fault windows excluded)."""
        if self.model == "bernoulli":
            return self.p
        b = self.bad_fraction
        return (1.0 - b) * self.loss_good + b * self.loss_bad


class LossProcess:
    """The loss decisions of one link, driven by a counter-based stream.

    Args:
        spec: the loss model.
        stream: stream of the link's loss draws.
        link_id: the link's integer id (first id of every draw).
    """

    def __init__(self, spec: LossSpec, stream: Stream, link_id: int) -> None:
        self.spec = spec
        self.stream = stream
        self.link_id = int(link_id)
        self._bad = np.zeros(0, dtype=np.bool_)  # chain state per slot, built lazily

    def expected_loss(self) -> float:
        """Stationary loss rate of the link (see :meth:`LossSpec.expected_loss`)."""
        return self.spec.expected_loss()

    # -- Gilbert–Elliott chain --------------------------------------------------

    def _extend(self, upto: int) -> None:
        """Build the chain state for every slot ``< upto`` (amortised doubling)."""
        have = self._bad.size
        if upto <= have:
            return
        size = max(upto, 2 * have, _MIN_CHUNK)
        spec = self.spec
        s = np.arange(have, size, dtype=np.int64)
        u = self.stream.uniform(self.link_id, _CHAIN_TAG, s)
        if have == 0:
            init = bool(u[0] < spec.bad_fraction)
        else:
            init = bool(self._bad[-1])
        # Slot s's map f_s on {good, bad}: constant (a reset) or identity / swap.
        to_bad = u < spec.p_gb  # f_s(good) is bad
        to_good = u < spec.p_bg  # f_s(bad) is good
        reset = to_bad != to_good  # constant map; its value is `to_bad`
        swap = to_bad & to_good
        if have == 0:
            reset[0] = False  # slot 0 has no transition: it is the initial state
            swap[0] = False
        idx = np.arange(s.size)
        last_reset = np.maximum.accumulate(np.where(reset, idx, -1))
        swaps = np.cumsum(swap, dtype=np.int64)
        has_reset = last_reset >= 0
        lr = np.maximum(last_reset, 0)
        base = np.where(has_reset, to_bad[lr], init)
        since = swaps - np.where(has_reset, swaps[lr], 0)
        state = base ^ (since % 2 == 1)
        self._bad = np.concatenate([self._bad, state])

    def bad_state(self, t: ArrayLike) -> NDArray[np.bool_]:
        """Whether the Gilbert–Elliott channel is in its bad state at times ``t``.

        Args:
            t: send times in seconds (``>= 0``).

        Returns:
            A boolean array of ``t``'s shape (at least 1-d).
        """
        ta = np.atleast_1d(np.asarray(t, dtype=np.float64))
        slots = np.floor(ta / self.spec.slot).astype(np.int64)
        if slots.size and slots.min() < 0:
            raise ValueError("loss: send times must be >= 0")
        if slots.size:
            self._extend(int(slots.max()) + 1)
        return self._bad[slots]

    # -- decisions --------------------------------------------------------------

    def lost(self, t: ArrayLike, *ids: ArrayLike, extra_p: ArrayLike = 0.0) -> NDArray[np.bool_]:
        """Whether each packet sent at ``t`` and keyed by ``ids`` is lost.

        Args:
            t: send times in seconds (scalar or array; used by Gilbert–Elliott).
            *ids: non-negative integer ids of the packet (scalars or arrays).
            extra_p: additional, independent loss probability (e.g. a fault
                window), scalar or per packet; applied with its own draw.

        Returns:
            A boolean array of the broadcast shape of ``t`` and ``ids``.
        """
        spec = self.spec
        if spec.model == "bernoulli":
            if spec.p == 0.0:
                out = np.zeros(_id_shape(ids), dtype=np.bool_)
            else:
                out = self.stream.uniform(self.link_id, *ids) < spec.p
        else:
            p_state = np.where(self.bad_state(t), spec.loss_bad, spec.loss_good)
            out = self.stream.uniform(self.link_id, *ids) < p_state
        if not (isinstance(extra_p, float | int) and extra_p == 0):
            ep = np.asarray(extra_p, dtype=np.float64)
            if np.any(ep > 0.0):
                out = out | (self.stream.uniform(self.link_id, _EXTRA_TAG, *ids) < ep)
        t_shape = np.shape(t)
        if t_shape and t_shape != out.shape:
            out = np.broadcast_to(out, np.broadcast_shapes(t_shape, out.shape)).copy()
        return out


def _id_shape(ids: tuple[ArrayLike, ...]) -> tuple[int, ...]:
    """The (at least 1-d) broadcast shape of a stream draw keyed by ``ids``."""
    if not ids:
        return (1,)
    return np.broadcast_shapes(*(np.atleast_1d(np.asarray(i)).shape for i in ids))
