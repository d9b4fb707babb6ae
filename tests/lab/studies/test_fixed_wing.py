"""The fixed-wing study's library: JSBSim's coefficients read from the installed minisgs
file, the glide-ratio cd_0 by hand, the inertia ridge (exact by the Euler equations), and
a short minisgs log whose logged surfaces, replayed through JSBSim's own coefficients in
our structure, reproduce JSBSim's roll rate (a reversed aileron fails it)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("jsbsim")

from sigma_lab.studies.fixed_wing import (  # noqa: E402
    glide_cd0,
    glider_start,
    inertia_ridge,
    jsbsim_coefficients,
)

from sigma_des.agents.atmosphere import gravity_scalar, isa_scalar  # noqa: E402
from sigma_des.tuning.flightlog import FlightLog  # noqa: E402
from sigma_des.tuning.glider_log import GlideSpec, fly_glider, glider_structure  # noqa: E402
from sigma_des.tuning.report import replayed, score  # noqa: E402
from sigma_des.tuning.spec import TuneSpec, with_values  # noqa: E402


@pytest.fixture(scope="module")
def start() -> object:
    return glider_start(glider_structure())


def test_jsbsim_coefficients_are_the_files() -> None:
    c = jsbsim_coefficients("minisgs", (-0.12, -0.05))
    # minisgs.xml: Clp -0.47, Clda 0.25, Cmalpha -0.573, Cmde -1.261, Cmq -9 + Cmadot -5.2
    assert c["cll_p"] == -0.47 and c["cll_da"] == 0.25 and c["cm_a"] == -0.573
    assert c["cm_de"] == -1.261 and c["cm_q"] == pytest.approx(-14.2)
    assert c["cl_q"] == 0.0 and c["cy_p"] == 0.0          # minisgs has no CLq, no CYp
    # CLwbh table points in [-0.14, -0.03]: (-0.1369, .06), (-0.1222, .12), (-0.09, .19),
    # (-0.0524, .26), (-0.0349, .33): least-squares slope and intercept
    a = np.array([-0.1369, -0.1222, -0.09, -0.0524, -0.0349])
    y = np.array([0.06, 0.12, 0.19, 0.26, 0.33])
    slope = ((a - a.mean()) * (y - y.mean())).sum() / ((a - a.mean()) ** 2).sum()
    assert c["cl_a"] == pytest.approx(slope) and c["cl_0"] == pytest.approx(
        y.mean() - slope * a.mean())


def test_glide_cd0_by_hand(start: object) -> None:
    # a steady glide at 10 m/s sinking 0.5 m/s: gamma = -asin(0.05); CL = W cos g / qS,
    # CD = W sin(-g) / qS; cd_0 = CD - cd_k CL^2
    n = 51
    t = np.arange(n) * 0.02
    obs = np.zeros((n, 12))
    obs[:, 0] = 10.0
    obs[:, 11] = 300.0 - 0.5 * t
    log = FlightLog("fixedwing", t, np.zeros((n, 4)), obs, "glide")
    p = start
    h = 300.0 - 0.5 * 0.49                  # mean altitude of the first 50 samples (1 s)
    rho = isa_scalar(h)[2]
    qs = 0.5 * rho * 100.0 * p.aero.s  # type: ignore[attr-defined]
    w = p.mass * gravity_scalar(h)  # type: ignore[attr-defined]
    g = -math.asin(0.05)
    cl, cd = w * math.cos(g) / qs, -w * math.sin(g) / qs
    want = cd - p.aero.cd_k * cl * cl  # type: ignore[attr-defined]
    assert 0.005 < want < 0.02 and glide_cd0(log, p) == pytest.approx(want)  # type: ignore[arg-type]


def test_replay_through_jsbsim_coefficients_and_the_inertia_ridge(start: object) -> None:
    log = fly_glider(GlideSpec(duration=6.0, warmup=4.0, noise=False))
    p = with_values(start, jsbsim_coefficients("minisgs", (-0.12, -0.05)))  # type: ignore[arg-type]
    spec = TuneSpec()
    win, sims = replayed(log, [p], spec)
    ch = score(win, sims[0], "fixedwing")["channels"]
    assert ch["p"]["r2"] > 0.95 and ch["phi"]["r2"] > 0.9
    flipped = log.act.copy()
    flipped[:, 1] *= -1.0
    bad = FlightLog(log.kind, log.t, flipped, log.obs, "flipped aileron")
    win_b, sims_b = replayed(bad, [p], spec)
    assert score(win_b, sims_b[0], "fixedwing")["channels"]["p"]["r2"] < 0.0
    # inertia and every moment coefficient x k: the same angular accelerations, the same
    # fitness (to rounding); inertia alone x k: a different motion
    for row in inertia_ridge(log, p, spec):
        assert row["both"] == pytest.approx(1.0, abs=1e-6)
        assert abs(row["inertia_only"] - 1.0) > 0.05


def test_trim_moments_of_jsbsim_s_own_coefficients(start: object) -> None:
    """At JSBSim's trimmed glides, JSBSim's Cmalpha alpha + Cmde de is a nearly constant
    -0.008 (the moment of its aero reference point 2.08 in above the CG balances it), so
    the logged elevator and angle of attack are consistent with its moment model."""
    from sigma_lab.studies.fixed_wing import trim_moments

    p = with_values(start, jsbsim_coefficients("minisgs", (-0.12, -0.05)))  # type: ignore[arg-type]
    rows = trim_moments(p, (9.0, 12.0))
    assert [r["speed"] for r in rows] == [9.0, 12.0]
    assert rows[0]["alpha"] > rows[1]["alpha"] and rows[0]["delta_e"] < rows[1]["delta_e"]
    for r in rows:
        assert -0.011 < r["cm"] < -0.005
        assert r["cm"] == pytest.approx(-0.573 * r["alpha"] - 1.261 * r["delta_e"])
    assert abs(rows[0]["cm"] - rows[1]["cm"]) < 0.003
