"""International Standard Atmosphere (ISO 2533 / ICAO 1993) and gravity vs altitude.

Troposphere (lapse rate -6.5 K/km) up to 11 km geopotential, isothermal
stratosphere to 20 km; altitudes are geometric metres above mean sea level and are
converted to geopotential height first, as the standard tables are tabulated in
geopotential height. :func:`isa_scalar` is the numba version used inside the
physics kernels; :func:`isa` is the vectorised numpy version for Python callers.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

__all__ = ["G0", "R_AIR", "isa", "isa_scalar", "gravity", "gravity_scalar"]

G0 = 9.80665             #: standard gravity (m/s^2), ISO 2533
R_AIR = 287.05287        #: specific gas constant of dry air (J/(kg K)), ISO 2533
T0 = 288.15              #: sea-level temperature (K)
P0 = 101325.0            #: sea-level pressure (Pa)
LAPSE = -0.0065          #: troposphere temperature gradient (K/m)
H_TROPO = 11000.0        #: tropopause geopotential height (m)
T_TROPO = T0 + LAPSE * H_TROPO                       # 216.65 K
P_TROPO = P0 * (T_TROPO / T0) ** (-G0 / (LAPSE * R_AIR))  # 22632.06 Pa
R_EARTH = 6356766.0      #: earth radius used for geopotential height (m), ISO 2533
_EXP = -G0 / (LAPSE * R_AIR)                          # 5.25588


@njit(cache=True)
def isa_scalar(h: float) -> tuple[float, float, float]:
    """(temperature K, pressure Pa, density kg/m^3) at geometric altitude ``h`` (m).

    Altitudes are clipped to [-1000, 20000] m, the range the layers above cover.
    """
    h = min(max(h, -1000.0), 20000.0)
    hg = R_EARTH * h / (R_EARTH + h)
    if hg <= H_TROPO:
        t = T0 + LAPSE * hg
        p = P0 * (t / T0) ** _EXP
    else:
        t = T_TROPO
        p = P_TROPO * math.exp(-G0 * (hg - H_TROPO) / (R_AIR * T_TROPO))
    return t, p, p / (R_AIR * t)


@njit(cache=True)
def gravity_scalar(h: float) -> float:
    """Gravity (m/s^2) at geometric altitude ``h``: inverse-square decay from G0."""
    k = R_EARTH / (R_EARTH + h)
    return G0 * k * k


def isa(h: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Vectorised :func:`isa_scalar`: (temperature, pressure, density) arrays."""
    h = np.clip(np.asarray(h, dtype=np.float64), -1000.0, 20000.0)
    hg = R_EARTH * h / (R_EARTH + h)
    t = np.where(hg <= H_TROPO, T0 + LAPSE * hg, T_TROPO)
    p = np.where(hg <= H_TROPO, P0 * (t / T0) ** _EXP,
                 P_TROPO * np.exp(-G0 * (hg - H_TROPO) / (R_AIR * T_TROPO)))
    return t, p, p / (R_AIR * t)


def gravity(h: ArrayLike) -> NDArray[np.float64]:
    """Vectorised :func:`gravity_scalar`."""
    k = R_EARTH / (R_EARTH + np.asarray(h, dtype=np.float64))
    return G0 * k * k
