"""``knee.png``: missed frames against N per message mode, live's runs and the DES's grid.

One panel per message mode: each method's live missed-frame fraction at the grid's
sizes (markers; the mean of a cell's runs) and the DES's on its finer grid (line), the
budget of the knee (5 %) dashed and each knee (the first N that does not hold, the
predicate of ``sigma-des capacity``) marked: live's solid, the DES's dotted.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from sigma_des.plotstyle import MIN_DPI, line_kw

__all__ = ["knee_plot"]


def knee_plot(points: dict[str, dict[str, dict[str, list[tuple[int, float]]]]],
              knees: list[dict[str, Any]], budget: float, path: Path) -> None:
    """Draw ``points[mode][method]["live" | "des"]`` (``(N, missed)`` pairs) and the
    knees of ``knees`` (``knee.csv``'s rows) into ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    modes = [m for m in ("node", "bundle") if m in points]
    if not modes:
        return
    fig, axes = plt.subplots(1, len(modes), figsize=(5.5 * len(modes), 4.2), squeeze=False,
                             layout="constrained")
    for ax, mode in zip(axes[0], modes, strict=True):
        for method, series in points[mode].items():
            kw = line_kw(method, n_points=len(series.get("des", [])))
            des = sorted(p for p in series.get("des", []) if math.isfinite(p[1]))
            live = sorted(p for p in series.get("live", []) if math.isfinite(p[1]))
            if des:
                ax.plot([n for n, _ in des], [100 * y for _, y in des], label=method, **kw)
            if live:
                ax.scatter([n for n, _ in live], [100 * y for _, y in live], s=40,
                           marker=kw["marker"], facecolors="none", edgecolors=kw["color"])
            for r in knees:
                if r["mode"] == mode and r["method"] == method:
                    for key, ls in (("live_knee", "-"), ("des_knee", ":")):
                        if r[key]:
                            ax.axvline(r[key], color=kw["color"], ls=ls, lw=1)
        ax.axhline(100 * budget, color="k", ls="--", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel("nodes N")
        ax.set_ylabel("missed frames (%)")
        ax.set_title(f"{mode} messages: live (hollow) and DES (line); knees: live solid, "
                     "DES dotted", fontsize=8)
        ax.legend(fontsize=8)
    fig.savefig(path, dpi=max(MIN_DPI, 110))
    plt.close(fig)
