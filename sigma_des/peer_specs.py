"""Parameters of the AirSim-style RPC peer architecture (the ``rpc`` method).

A frozen, validated spec class embedded in :class:`~sigma_des.config.Scenario` as
``[rpc]``. (The other peer architecture, DDS/RTPS middleware, is the net layer's:
:class:`sigma_des.net.spec.DdsSpec`, ``[dds]``.) Every default names its source;
where no published figure exists the value is an estimate and says so
(docs/MODEL.md, "Peer architectures").

Sources:
    [AIRSIM] AirSim docs/API (msgpack-rpc over TCP, port 41451; the Python client
            ``msgpackrpc.Client.call`` blocks until the response).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sigma_des.core.validate import require_nonneg
from sigma_des.net.latency import Dist

__all__ = ["RpcSpec"]


@dataclass(frozen=True)
class RpcSpec:
    """AirSim-style synchronous RPC: the server calls every vehicle each frame.

    One frame: the server sends a request (a trigger) to each vehicle, at most
    ``in_flight`` calls outstanding (0 = one per vehicle, all at once, as
    independent blocking clients); each vehicle steps and responds with its state;
    the server's game thread handles each response (``call_time``), then renders
    the frame (``render_time`` + ``render_per_vehicle`` × N); the next frame starts
    when the render is done, not sooner than ``1/f_trig`` after the previous one.
    Rendering and the calls share that one thread, so render load delays physics.

    Attributes:
        in_flight: most calls outstanding at once (0 = one per vehicle) [AIRSIM:
            a msgpack-rpc client's ``call`` blocks, so one outstanding call per client].
        call_time: game-thread time per handled call (API dispatch, msgpack
            serialization of the vehicle state); estimate (s).
        render_time: render time of a frame at zero vehicles; estimate for an Unreal
            scene at ~60-100 fps (s).
        render_per_vehicle: extra render time per vehicle drawn; estimate (s).
    """

    in_flight: int = 0
    call_time: Dist = field(default_factory=lambda: Dist(dist="constant", value=0.0003))
    render_time: Dist = field(
        default_factory=lambda: Dist(dist="lognormal", mean=0.008, std=0.003)
    )
    render_per_vehicle: float = 0.0002

    def __post_init__(self) -> None:
        require_nonneg(self, "in_flight", "render_per_vehicle")
