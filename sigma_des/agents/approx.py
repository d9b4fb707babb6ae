"""Cheap deterministic approximations for the kernels' hot loop (numba).

libm's ``atan2``/``asin`` cost tens of nanoseconds each and dominated the
per-sub-step cost of the autopilots; these polynomial versions are pure
arithmetic (hence bit-reproducible and row-independent like the rest of the
kernel) and accurate to 1e-5 rad, far below anything a controller notices.
They are used only inside autopilot loops; published states use numpy's exact
functions.

:func:`sqrt` is not an approximation: it is the correctly rounded square root
(the same bits as ``math.sqrt``) emitted as the LLVM ``llvm.sqrt`` intrinsic.
``math.sqrt`` compiles to a libm call (which may set ``errno``), and the
vectoriser cannot predicate a call, so a lane loop with a square root under a
branch would stay scalar; the intrinsic has no side effect and vectorises.
"""

from __future__ import annotations

import math
from typing import Any

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

__all__ = ["sqrt", "atan2_fast", "asin_fast", "wrap_pi"]

_HALF_PI = 0.5 * math.pi


@intrinsic
def _llvm_sqrt(typingctx: Any, x: Any) -> Any:
    """``llvm.sqrt.f64`` of a float64 (typing and code generation for numba)."""
    if not isinstance(x, types.Float):
        return None

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        val = builder.fpext(args[0], ir.DoubleType()) if x != types.float64 else args[0]
        fn = builder.module.declare_intrinsic("llvm.sqrt", [ir.DoubleType()])
        return builder.call(fn, [val])

    return types.float64(x), codegen


@njit(cache=True, inline="always")
def sqrt(v: float) -> float:
    """Correctly rounded square root (NaN below 0), vectorisable (module doc)."""
    return _llvm_sqrt(v)  # type: ignore[call-arg]  # numba passes the typing context


@njit(cache=True, inline="always")
def _atan_unit(z: float) -> float:
    # Abramowitz & Stegun 4.4.49: |error| <= 1e-5 on [-1, 1].
    z2 = z * z
    return z * (0.9998660 + z2 * (-0.3302995 + z2 * (0.1801410
                                                     + z2 * (-0.0851330 + z2 * 0.0208351))))


@njit(cache=True, inline="always")
def atan2_fast(y: float, x: float) -> float:
    """``atan2(y, x)`` to 1e-5 rad (0 for the origin)."""
    ax, ay = abs(x), abs(y)
    if ax == 0.0 and ay == 0.0:
        return 0.0
    if ay <= ax:
        a = _atan_unit(ay / ax)
    else:
        a = _HALF_PI - _atan_unit(ax / ay)
    if x < 0.0:
        a = math.pi - a
    return -a if y < 0.0 else a


@njit(cache=True, inline="always")
def asin_fast(s: float) -> float:
    """``asin(s)`` to 1e-5 rad, ``s`` clipped to [-1, 1]."""
    s = min(max(s, -1.0), 1.0)
    return atan2_fast(s, sqrt(1.0 - s * s))


@njit(cache=True, inline="always")
def wrap_pi(a: float) -> float:
    """Angle wrapped to [-pi, pi] (branches instead of fmod: cheaper, same result)."""
    while a > math.pi:
        a -= 2.0 * math.pi
    while a < -math.pi:
        a += 2.0 * math.pi
    return a
