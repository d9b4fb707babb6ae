"""Fit reports of a tuning run: R² / RMS before and after, and Figs. 14–15-like plots.

The paper scores the attitude loop on a separate log: the quadrotor on pitch and
roll *angles*, the fixed wing on pitch and roll *rates* (:data:`PAPER_CHANNELS`);
we report those two (their mean R² is "attitude R²") plus every attitude and
rate channel. A replay here is the tuning replay (same windows, restarting from
the log every ``tune.segment`` s): R² measures the fit over that horizon.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents.params import AircraftParams
from sigma_des.agents.wind import WindConfig
from sigma_des.tuning.fitness import fit_metrics
from sigma_des.tuning.flightlog import FlightLog, resample
from sigma_des.tuning.replay import Windows, param_matrix, replay_batch, windows
from sigma_des.tuning.spec import TuneSpec

__all__ = ["PAPER_CHANNELS", "PAPER_VALUES", "score", "replayed", "plot_fit"]

#: (pitch, roll) channels the paper scores per aircraft kind.
PAPER_CHANNELS: dict[str, tuple[str, str]] = {"quadrotor": ("theta", "phi"),
                                               "fixedwing": ("q", "p")}
#: The paper's validation figures (§V.A.2): RMS pitch, RMS roll, R².
PAPER_VALUES: dict[str, dict[str, float]] = {
    "quadrotor": {"rms_pitch": 0.1042, "rms_roll": 0.036, "r2": 0.93},
    "fixedwing": {"rms_pitch": 0.062, "rms_roll": 0.073, "r2": 0.91},
}
_ALL = ("phi", "theta", "psi", "p", "q", "r")


def replayed(log: FlightLog, params: list[AircraftParams], spec: TuneSpec,
             wind: WindConfig | None = None) -> tuple[Windows, NDArray[np.float64]]:
    """The log's windows and their replay by every parameter set, ``(P, S, M + 1, 12)``."""
    win = windows(resample(log, spec.rate), spec.segment)
    return win, replay_batch(win, param_matrix(params, wind))


def score(win: Windows, sim: NDArray[np.float64], kind: str) -> dict[str, Any]:
    """Per-channel RMS / R² of one replay and the paper's summary figures."""
    m = fit_metrics(win, sim, _ALL)
    pitch, roll = PAPER_CHANNELS[kind]
    return {"channels": m, "rms_pitch": m[pitch]["rms"], "rms_roll": m[roll]["rms"],
            "r2": 0.5 * (m[pitch]["r2"] + m[roll]["r2"]),
            "pitch_channel": pitch, "roll_channel": roll}


def plot_fit(path: Path, win: Windows, sims: dict[str, NDArray[np.float64]], kind: str,
             title: str) -> Path | None:
    """Logged vs each replay for pitch and roll (None if matplotlib is not installed)."""
    try:
        import matplotlib
    except ImportError:
        return None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sigma_des.tuning.flightlog import STATE_COLUMNS

    chans = PAPER_CHANNELS[kind]
    unit = "rad" if kind == "quadrotor" else "rad/s"
    t = (np.arange(win.count)[:, None] * win.steps + np.arange(win.steps + 1)[None, :]) * win.dt
    fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True, layout="constrained")
    for ax, c, lab in zip(axes, chans, ("(a) pitch", "(b) roll"), strict=True):
        j = STATE_COLUMNS.index(c)
        ax.plot(t.ravel(), win.obs[:, :, j].ravel(), "k-", lw=1.2, label="logged")
        for (name, sim), style in zip(sims.items(), ("C1--", "C0-"), strict=False):
            y = np.concatenate([np.append(sim[s, :, j], np.nan) for s in range(win.count)])
            tt = np.concatenate([np.append(t[s], np.nan) for s in range(win.count)])
            ax.plot(tt, y, style, lw=1.0, label=name)
        ax.set_ylabel(f"{c} ({unit})")
        ax.set_title(lab, loc="left", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, ncol=3)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(title, fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
