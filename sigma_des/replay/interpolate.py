"""Trajectory interpolation: SciPy's standard interpolants and our dynamic-window Hermite.

>>> import numpy as np
>>> from sigma_des.replay import interpolate
>>> t = np.array([0.0, 1.0, 2.0])
>>> p = np.array([[0.0], [1.0], [4.0]])
>>> interpolate(t, p, method="linear", at=[0.5, 1.5]).ravel().tolist()
[0.5, 2.5]
>>> v = np.array([[0.0], [2.0], [4.0]])                      # p = t², exactly
>>> round(float(interpolate(t, p, method="hermite-dw", at=[0.5], velocities=v)[0, 0]), 12)
0.25

Baselines (``linear``, ``cubic``, ``pchip``, ``akima``) are ``numpy.interp`` /
``scipy.interpolate`` (``CubicSpline``, ``PchipInterpolator``, ``Akima1DInterpolator``)
on the positions alone. ``hermite-dw`` is a piecewise cubic Hermite spline
(``scipy.interpolate.CubicHermiteSpline``) through the logged positions whose tangent at
each knot is fitted to the logged velocities within a dynamic window
(:mod:`sigma_des.replay.window`): a least-squares line through the velocities of knots
``j − W_j … j + W_j``; with ``W_j = 0`` the tangent is the logged velocity. Every method
passes through the samples, so a replay reproduces the recorded values at the recorded
instants exactly. Attitude goes on SO(3) by slerp (:func:`slerp_attitude`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import (
    Akima1DInterpolator,
    CubicHermiteSpline,
    CubicSpline,
    PchipInterpolator,
)
from scipy.spatial.transform import Rotation, Slerp

from sigma_des.replay.window import WindowRule, window_sizes

__all__ = ["INTERP_METHODS", "MIN_SAMPLES", "hermite_tangents", "interpolate",
           "slerp_attitude", "slerp_segments"]

_F = NDArray[np.float64]

#: Interpolation methods of :func:`interpolate`.
INTERP_METHODS: tuple[str, ...] = ("hermite-dw", "linear", "cubic", "pchip", "akima")
#: Fewest samples each method needs (cubic: not-a-knot needs 4; Akima 5: two each side).
MIN_SAMPLES: dict[str, int] = {"hermite-dw": 2, "linear": 2, "cubic": 4, "pchip": 2,
                               "akima": 5}


def _check(times: _F, samples: _F, method: str) -> None:
    if method not in INTERP_METHODS:
        raise ValueError(f"unknown method {method!r}; allowed: {', '.join(INTERP_METHODS)}")
    if times.ndim != 1 or samples.shape[0] != times.size:
        raise ValueError(f"times ({times.shape}) and samples ({samples.shape}) do not match")
    need = MIN_SAMPLES[method]
    if times.size < need:
        raise ValueError(f"method {method} needs at least {need} samples, got {times.size}")
    if not np.all(np.isfinite(times)) or not np.all(np.isfinite(samples)):
        raise ValueError("times and samples must be finite")
    bad = np.flatnonzero(np.diff(times) <= 0)
    if bad.size:
        j = int(bad[0]) + 1
        raise ValueError(f"timestamps must increase strictly: t[{j}] = {float(times[j])!r} "
                         f"after t[{j - 1}] = {float(times[j - 1])!r}")


def hermite_tangents(times: _F, vel: _F, sizes: NDArray[np.int64]) -> _F:
    """Tangents of the dynamic-window Hermite spline.

    At knot ``j`` a straight line ``v(τ) = b + cτ`` (``τ = t − t_j``) is fitted by least
    squares to the logged velocities of knots ``j − W_j … j + W_j`` (clipped at the
    ends); the tangent is ``b``. This averages velocity noise without the lag of a plain
    moving average (a constant acceleration is followed exactly). Knots with
    ``W_j = 0`` keep their logged velocity.
    """
    m = vel.shape[0]
    out = vel.copy()
    for wj in np.unique(sizes).tolist():
        if wj == 0:
            continue
        js = np.flatnonzero(sizes == wj)
        off = np.arange(-wj, wj + 1)
        raw = js[:, None] + off[None, :]
        idx = np.clip(raw, 0, m - 1)
        om = ((raw >= 0) & (raw < m)).astype(float)  # (K, L) weights: 0 beyond the ends
        tau = times[idx] - times[js][:, None]
        s0 = om.sum(axis=1)
        s1 = (om * tau).sum(axis=1)
        s2 = (om * tau**2).sum(axis=1)
        det = s0 * s2 - s1**2
        for c in range(vel.shape[1]):
            y = vel[idx, c]
            t0 = (om * y).sum(axis=1)
            t1 = (om * tau * y).sum(axis=1)
            out[js, c] = (s2 * t0 - s1 * t1) / det
    return out


def interpolate(
    times: ArrayLike,
    samples: ArrayLike,
    method: str = "hermite-dw",
    at: ArrayLike | None = None,
    *,
    velocities: ArrayLike | None = None,
    attitudes: ArrayLike | None = None,
    window: WindowRule | None = None,
) -> _F:
    """Interpolate a sampled trajectory at new instants.

    Args:
        times: ``(m,)`` sample times, strictly increasing (s).
        samples: ``(m,)`` or ``(m, d)`` values (e.g. NED positions).
        method: one of :data:`INTERP_METHODS`.
        at: query times; None: the sample times. Outside ``[times[0], times[-1]]`` the
            result is NaN (no extrapolation).
        velocities: ``(m, d)`` logged derivatives (``hermite-dw``; default: finite
            differences, ``numpy.gradient``).
        attitudes: ``(m, 3)`` logged Euler angles for the window's attitude term.
        window: the window rule (default :class:`WindowRule()`).

    Returns:
        ``(len(at), d)`` values (``(len(at),)`` if ``samples`` was 1-D).

    Raises:
        ValueError: unknown method, too few samples, non-finite or non-monotone input.
    """
    t = np.asarray(times, dtype=float)
    y = np.asarray(samples, dtype=float)
    flat = y.ndim == 1
    y2 = y[:, None] if flat else y
    _check(t, y2, method)
    q = t.copy() if at is None else np.atleast_1d(np.asarray(at, dtype=float))
    out = np.full((q.size, y2.shape[1]), np.nan)
    inside = (q >= t[0]) & (q <= t[-1])
    qi = q[inside]
    if method == "linear":
        val = np.stack([np.interp(qi, t, y2[:, c]) for c in range(y2.shape[1])], axis=1)
    elif method == "cubic":
        val = CubicSpline(t, y2, axis=0)(qi)
    elif method == "pchip":
        val = PchipInterpolator(t, y2, axis=0)(qi)
    elif method == "akima":
        val = Akima1DInterpolator(t, y2, axis=0)(qi)
    else:
        if velocities is None:
            v = np.gradient(y2, t, axis=0)
        else:
            v = np.asarray(velocities, dtype=float).reshape(y2.shape)
        att = None if attitudes is None else np.asarray(attitudes, dtype=float)
        rule = window or WindowRule()
        sizes = window_sizes(rule, v, att)
        tang = hermite_tangents(t, v, sizes)
        val = CubicHermiteSpline(t, y2, tang, axis=0)(qi)
    # at the knots every interpolant equals the sample: make it exact to the last bit
    k = np.searchsorted(t, qi)
    hit = (k < t.size) & (t[np.minimum(k, t.size - 1)] == qi)
    val[hit] = y2[k[hit]]
    out[inside] = val
    return out[:, 0] if flat else out


def slerp_attitude(times: ArrayLike, euler: ArrayLike, at: ArrayLike) -> _F:
    """Euler angles ``(φ, θ, ψ)`` interpolated on SO(3) by slerp (NaN outside the span).

    Args:
        times: ``(m,)`` strictly increasing sample times (m >= 2).
        euler: ``(m, 3)`` Z-Y-X Euler angles (rad).
        at: query times.
    """
    t = np.asarray(times, dtype=float)
    e = np.asarray(euler, dtype=float).reshape(-1, 3)
    _check(t, e, "linear")
    q = np.atleast_1d(np.asarray(at, dtype=float))
    out = np.full((q.size, 3), np.nan)
    inside = (q >= t[0]) & (q <= t[-1])
    rot = Rotation.from_euler("ZYX", e[:, ::-1])
    res = Slerp(t, rot)(q[inside]).as_euler("ZYX")[:, ::-1]
    k = np.searchsorted(t, q[inside])
    hit = (k < t.size) & (t[np.minimum(k, t.size - 1)] == q[inside])
    res[hit] = e[k[hit]]
    out[inside] = res
    return out


def _quat(e: _F) -> _F:
    """Unit quaternions (x, y, z, w) of Z-Y-X Euler angles (φ, θ, ψ) (SciPy's convention)."""
    hp, ht, hs = e[:, 0] / 2, e[:, 1] / 2, e[:, 2] / 2
    cp, sp, ct, st, cs, ss = np.cos(hp), np.sin(hp), np.cos(ht), np.sin(ht), np.cos(hs), np.sin(hs)
    return np.stack([sp * ct * cs - cp * st * ss, cp * st * cs + sp * ct * ss,
                     cp * ct * ss - sp * st * cs, cp * ct * cs + sp * st * ss], axis=1)


def _euler(q: _F) -> _F:
    """Z-Y-X Euler angles (φ, θ, ψ) of unit quaternions (x, y, z, w)."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    phi = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    theta = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    psi = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([phi, theta, psi], axis=1)


def slerp_segments(times: _F, euler: _F, starts: NDArray[np.intp], at: _F,
                   seg: NDArray[np.intp]) -> _F:
    """:func:`slerp_attitude` for many trajectories at once (the replay's fast path).

    The same spherical linear interpolation as ``scipy.spatial.transform.Slerp`` (equal to
    it to ~1e-12, tested), written on quaternion arrays in numpy: SciPy's ``Rotation``
    products cost microseconds per element, seconds for a 1000-node replay.

    Args:
        times: concatenated sample times of every trajectory (each strictly increasing,
            at least 2 samples).
        euler: ``(m, 3)`` Z-Y-X Euler angles of those samples.
        starts: ``(k + 1,)`` start of each trajectory in ``times`` (last entry ``m``).
        at: query times, each inside its trajectory's span.
        seg: trajectory index of each query, non-decreasing (queries grouped by trajectory).

    Returns:
        ``(len(at), 3)`` Euler angles; exactly the sample's at a sample time.
    """
    lo, hi = starts[seg], starts[seg + 1]
    j = np.empty(at.size, dtype=np.intp)
    qs = np.searchsorted(seg, np.arange(starts.size))  # each trajectory's block of queries
    for s in range(starts.size - 1):
        a, b, qa, qb = int(starts[s]), int(starts[s + 1]), int(qs[s]), int(qs[s + 1])
        j[qa:qb] = a + np.searchsorted(times[a:b], at[qa:qb], side="right") - 1
    j = np.clip(j, lo, hi - 2)
    frac = (at - times[j]) / (times[j + 1] - times[j])
    quat = _quat(euler)
    q0, q1 = quat[j], quat[j + 1]
    dot = np.einsum("ij,ij->i", q0, q1)
    q1 = np.where(dot[:, None] < 0, -q1, q1)  # the short way round
    ang = np.arccos(np.clip(np.abs(dot), -1.0, 1.0))
    small = ang < 1e-9
    sin = np.where(small, 1.0, np.sin(ang))
    w0 = np.where(small, 1 - frac, np.sin((1 - frac) * ang) / sin)
    w1 = np.where(small, frac, np.sin(frac * ang) / sin)
    q = w0[:, None] * q0 + w1[:, None] * q1
    out = _euler(q / np.linalg.norm(q, axis=1)[:, None])
    out[at == times[j]] = euler[j[at == times[j]]]
    out[at == times[j + 1]] = euler[j[at == times[j + 1]] + 1]
    return out
