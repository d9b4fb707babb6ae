"""Compiled pieces of the built-in behaviour rules (behaviours.py, formation.py).

Each kernel does the very floating-point operations of the numpy expression it
replaces, in the same order (``tests/agents/test_rule_kernels.py`` checks them bit for
bit against those expressions on random cases). What they leave out on purpose:

* **transcendental functions** (``cos``, ``sin``, ``arctan2``, ``hypot``) stay numpy
  calls made by the callers: numpy's float64 ``arctan2`` uses SIMD (SVML) code where
  the CPU has AVX-512 and differs from the C library's ``atan2``, which compiled code
  calls, in the last bit of ≈ 7 % of values on the machine this was written on;
* **the k-d tree of separation** stays scipy's where the order of the pairs matters:
  the repulsion of a node is a sum over its pairs in the order ``query_pairs`` visits
  them, which depends on how the tree's build orders the points inside a leaf. Where
  no node is in more than two pairs that order changes no bit (a sum ``(0 + x) + y``
  of two terms is the same either way), and a compiled grid search
  (:func:`close_pairs`) finds the pairs instead, unless a pair's distance is too close
  to the radius to be sure the tree would count it alike.

A kernel's cost is one call (a few µs) instead of tens of numpy calls on ``n``-long
arrays per command tick.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["known_positions", "close_pairs", "separation_push", "priority_take",
           "any_active", "slots_kernel", "velocity_field", "carrot_kernel"]

#: :func:`close_pairs`: the relative margin around the radius (squared) inside which a
#: pair is too close to call; a grid cell is the radius times ``1 + 100 * CLOSE_BAND``.
CLOSE_BAND = 1e-6


@njit(cache=True)
def known_positions(obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of ``obs`` (``(n, 12)``) whose position (columns 9–11) is finite, and
    those positions as a contiguous ``(k, 3)`` array: ``np.flatnonzero(np.isfinite(pos)
    .all(axis=1))`` and ``pos[known]`` of ``pos = obs[:, [9, 10, 11]]``."""
    n = obs.shape[0]
    rows = np.empty(n, dtype=np.int64)
    k = 0
    for r in range(n):
        if (math.isfinite(obs[r, 9]) and math.isfinite(obs[r, 10])
                and math.isfinite(obs[r, 11])):
            rows[k] = r
            k += 1
    pts = np.empty((k, 3))
    for a in range(k):
        for c in range(3):
            pts[a, c] = obs[rows[a], 9 + c]
    return rows[:k], pts


@njit(cache=True)
def close_pairs(pts: np.ndarray, radius: float) -> tuple[np.ndarray, bool]:
    """The pairs ``(a, b)``, ``a < b``, of rows of ``pts`` (``(k, 3)``, finite) within
    ``radius`` of each other, as ``query_pairs(radius)`` of a k-d tree finds them, but in
    an order of their own; and whether they may stand for the tree's (True), else
    ``(empty, False)``: the caller asks the tree.

    A grid of square cells (north, east) a little wider than the radius; each point
    meets the points of its own and the eight cells around. The distance is the tree's
    ``(d0² + d1²) + d2²``; False when one is within ``CLOSE_BAND`` (relative, plus
    a margin for the tree's rounding of distances far from the origin) of the squared
    radius (the tree's rounding could then count the pair otherwise), when a point is
    in three pairs or more (its repulsion would depend on the order of its pairs), or
    when the grid would be too large (points far apart) or the radius not > 0.
    """
    k = pts.shape[0]
    none = np.empty((0, 2), dtype=np.int64)
    if not radius > 0:
        return none, False
    if k < 2:
        return none, True
    r2 = radius * radius
    lo0, lo1, hi0, hi1, big = pts[0, 0], pts[0, 1], pts[0, 0], pts[0, 1], 0.0
    for a in range(k):
        lo0, hi0 = min(lo0, pts[a, 0]), max(hi0, pts[a, 0])
        lo1, hi1 = min(lo1, pts[a, 1]), max(hi1, pts[a, 1])
        big = max(big, abs(pts[a, 0]) + abs(pts[a, 1]) + abs(pts[a, 2]))
    band = CLOSE_BAND * r2 + 1e-12 * big * big
    cell = radius * (1.0 + 100.0 * CLOSE_BAND)
    nx = (hi0 - lo0) / cell + 1.0
    ny = (hi1 - lo1) / cell + 1.0
    if not (band < 10.0 * CLOSE_BAND * r2 and nx * ny < 4.0 * k + 65536.0):
        return none, False
    nyi = int(ny)
    cells = int(nx) * nyi
    of = np.empty(k, dtype=np.int64)
    start = np.zeros(cells + 1, dtype=np.int64)
    for a in range(k):
        c = int((pts[a, 0] - lo0) / cell) * nyi + int((pts[a, 1] - lo1) / cell)
        of[a] = c
        start[c + 1] += 1
    for c in range(cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    member = np.empty(k, dtype=np.int64)
    for a in range(k):
        member[fill[of[a]]] = a
        fill[of[a]] += 1
    pairs = np.empty((k, 2), dtype=np.int64)  # more than k pairs: a point is in three
    count = np.zeros(k, dtype=np.int64)
    m = 0
    for a in range(k):
        ix, iy = of[a] // nyi, of[a] % nyi
        for jx in range(max(ix - 1, 0), min(ix + 2, cells // nyi)):
            for jy in range(max(iy - 1, 0), min(iy + 2, nyi)):
                c = jx * nyi + jy
                for q in range(start[c], start[c + 1]):
                    b = member[q]
                    if b <= a:
                        continue
                    d0 = pts[a, 0] - pts[b, 0]
                    d1 = pts[a, 1] - pts[b, 1]
                    d2 = pts[a, 2] - pts[b, 2]
                    dd = (d0 * d0 + d1 * d1) + d2 * d2
                    if dd > r2 + band:
                        continue
                    if dd >= r2 - band or m == k:
                        return none, False
                    count[a] += 1
                    count[b] += 1
                    if count[a] > 2 or count[b] > 2:
                        return none, False
                    pairs[m, 0] = a
                    pairs[m, 1] = b
                    m += 1
    return pairs[:m].copy(), True


@njit(cache=True)
def separation_push(pts: np.ndarray, known: np.ndarray, pairs: np.ndarray, radius: float,
                    n: int) -> tuple[np.ndarray, np.ndarray]:
    """Repulsion ``(n, 3)`` and deepest intrusion ``(n,)`` of separation's pairs.

    For pair ``p = (a, b)`` of ``pts`` (rows ``i = known[a]``, ``j = known[b]``):
    ``d = pos_i - pos_j``, ``dist = max(|d|, 1e-6)`` (``np.linalg.norm``'s sum of
    squares, ``(d0² + d1²) + d2²``), ``push = d / dist * ((radius - dist) / radius)``;
    then, as ``np.add.at`` would, ``rep[i] += push`` over the pairs in order, then
    ``rep[j] += -push`` over the pairs in order, and the running maxima of ``radius -
    dist`` into ``depth`` at ``i`` then ``j`` (the repulsion's sums in the order of the
    pairs: the same bits as the numpy expressions, whatever that order is).
    """
    rep = np.zeros((n, 3))
    depth = np.zeros(n)
    m = pairs.shape[0]
    push = np.empty((m, 3))
    gap = np.empty(m)
    d = np.empty(3)
    for p in range(m):
        a, b = pairs[p, 0], pairs[p, 1]
        for c in range(3):
            d[c] = pts[a, c] - pts[b, c]
        dist = math.sqrt((d[0] * d[0] + d[1] * d[1]) + d[2] * d[2])
        if not dist >= 1e-6:  # np.maximum: NaN stays NaN
            dist = 1e-6 if dist == dist else dist
        f = (radius - dist) / radius
        for c in range(3):
            push[p, c] = d[c] / dist * f
        gap[p] = radius - dist
    for p in range(m):
        i = known[pairs[p, 0]]
        for c in range(3):
            rep[i, c] += push[p, c]
    for p in range(m):
        j = known[pairs[p, 1]]
        for c in range(3):
            rep[j, c] += -push[p, c]
    for side in range(2):
        for p in range(m):
            i = known[pairs[p, side]]
            if gap[p] > depth[i]:
                depth[i] = gap[p]
    return rep, depth


@njit(cache=True)
def any_active(trig: np.ndarray, threshold: float, valid: np.ndarray) -> bool:
    """``((trig >= threshold) & valid).any()``."""
    for r in range(trig.shape[0]):
        if trig[r] >= threshold and valid[r]:
            return True
    return False


@njit(cache=True)
def priority_take(trig: np.ndarray, threshold: float, valid: np.ndarray, a: np.ndarray,
                  weight: float, best: np.ndarray, best_w: np.ndarray) -> None:
    """One rule of the ``priority`` combination: the rows where the rule is active
    (``trig >= threshold``, valid, an action in column 0) and outweighs the rules taken
    so far get its action ``a`` and weight (copies only: no arithmetic)."""
    for r in range(trig.shape[0]):
        if trig[r] >= threshold and valid[r] and not np.isnan(a[r, 0]) \
                and weight > best_w[r]:
            for c in range(best.shape[1]):
                best[r, c] = a[r, c]
            best_w[r] = weight


@njit(cache=True)
def slots_kernel(obs: np.ndarray, leader: int, d: float, cos_theta: float,
                 sin_theta: float, c: float, s: float) -> np.ndarray:
    """``formation_slots``' arithmetic (``c``, ``s``: cos and sin of the leader's
    heading, ``cos_theta``, ``sin_theta`` of the V's angle, computed by the caller)."""
    n = obs.shape[0]
    out = np.empty((n, 2))
    north, east = obs[leader, 9], obs[leader, 10]
    for i in range(n):
        rank = i + 1 if i < leader else i
        if i == leader:
            rank = 0
        row = np.ceil(rank / 2.0)
        side = 1.0 if rank % 2 == 1 else -1.0
        dx = -row * d * cos_theta
        dy = side * row * d * sin_theta
        out[i, 0] = north + c * dx - s * dy
        out[i, 1] = east + s * dx + c * dy
    return out


@njit(cache=True)
def velocity_field(obs: np.ndarray, slots: np.ndarray, vn0: float, ve0: float,
                   k_pos: float) -> tuple[np.ndarray, np.ndarray]:
    """The velocity-field law's ``vn = vn0 + k_pos (slot_n - x_n)`` and ``ve = ve0 +
    k_pos (slot_e - x_e)`` of every row."""
    n = obs.shape[0]
    vn = np.empty(n)
    ve = np.empty(n)
    for r in range(n):
        vn[r] = vn0 + k_pos * (slots[r, 0] - obs[r, 9])
        ve[r] = ve0 + k_pos * (slots[r, 1] - obs[r, 10])
    return vn, ve


@njit(cache=True)
def carrot_kernel(pos: np.ndarray, corners: np.ndarray, seg_len: np.ndarray,
                  starts: np.ndarray, ends: np.ndarray, d: np.ndarray, perim: float,
                  lookahead: float) -> np.ndarray:
    """``rectangle_carrot``'s arithmetic for the rows of ``pos`` (``(m, 2)``), the
    rectangle's arrays given: per side ``c`` the projection parameter ``t = clip((r0 d0 +
    r1 d1) / len², 0, 1)`` of ``r = pos - corner`` (numpy's clip: ``-0.0`` becomes
    ``0.0``), the distance ``sqrt(e0² + e1²)`` to
    the projection, the nearest side (the first of equal distances), the perimeter
    position ``((start + t len) + lookahead) mod perim`` (numpy's floating remainder),
    its side (``searchsorted(ends, s, 'right')`` clipped to 3) and the carrot."""
    m = pos.shape[0]
    out = np.empty((m, 2))
    nseg = corners.shape[0]
    for r in range(m):
        best, kbest, tbest = np.inf, -1, 0.0
        for c in range(nseg):
            r0 = pos[r, 0] - corners[c, 0]
            r1 = pos[r, 1] - corners[c, 1]
            t = (r0 * d[c, 0] + r1 * d[c, 1]) / (seg_len[c] * seg_len[c])
            if t == t:  # np.clip: min(max(t, 0), 1), NaN stays NaN, -0.0 becomes 0.0
                t = t if t > 0.0 else 0.0
                t = t if t < 1.0 else 1.0
            e0 = pos[r, 0] - (corners[c, 0] + t * d[c, 0])
            e1 = pos[r, 1] - (corners[c, 1] + t * d[c, 1])
            dist = math.sqrt(e0 * e0 + e1 * e1)
            if kbest < 0 or dist < best or (dist != dist and best == best):  # argmin
                best, kbest, tbest = dist, c, t
        a = (starts[kbest] + tbest * seg_len[kbest]) + lookahead
        s = np.fmod(a, perim)  # np.remainder: fmod (exact), then the sign of perim
        if s != 0.0:
            if (perim < 0.0) != (s < 0.0):
                s += perim
        else:
            s = math.copysign(0.0, perim)
        seg = 0
        while seg < ends.shape[0] and not s < ends[seg]:  # searchsorted, side='right'
            seg += 1
        seg = min(seg, nseg - 1)
        frac = (s - starts[seg]) / seg_len[seg]
        out[r, 0] = corners[seg, 0] + frac * d[seg, 0]
        out[r, 1] = corners[seg, 1] + frac * d[seg, 1]
    return out
