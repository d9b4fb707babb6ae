"""The delay study's conditions and paired statistics, by hand."""

from __future__ import annotations

import math

import pytest
from scipy import stats
from sigma_lab.studies.delay import cells, env_kwargs, paired_cells


def test_cells_and_their_env_arguments() -> None:
    assert cells([0.05, 0.2], ["bides", "none"]) == [
        "perfect", "bides@50ms", "none@50ms", "bides@200ms", "none@200ms"]
    kw = env_kwargs("none@200ms", 5, 30, 0.1)
    assert kw["method"] == "none" and kw["perfect_info"] is False
    assert kw["scenario"]["net.host_link.latency"] == {"dist": "normal", "mean": 0.2,
                                                       "std": 0.2 / 5}
    assert kw["scenario"]["net.host_link.loss"] == {"p": 0.1}
    assert env_kwargs("perfect", 5, 30, 0.1)["perfect_info"] is True
    assert kw["metrics"] is False and env_kwargs("perfect", 5, 30, 0.1)["metrics"] is False


def test_paired_statistics_hand_computed() -> None:
    evals = []
    for s, (dv, pv) in enumerate([(1.0, 0.0), (2.0, 0.0), (3.0, 1.0)]):
        evals += [{"trained": "none@50ms", "seed": s, "evaluated": "none@50ms", "fitness": dv},
                  {"trained": "perfect", "seed": s, "evaluated": "none@50ms", "fitness": pv}]
    evals += [{"trained": n, "seed": -1, "evaluated": "none@50ms", "fitness": -1.0}
              for n in ("untrained", "naive", "extrapolating")]
    (row,) = paired_cells(evals, ["perfect", "none@50ms"], [0, 1, 2])
    # differences 1, 2, 2: mean 5/3, sd 1/sqrt(3), t = 5; df 2: P(T > t) = 1/2 - t / (2
    # sqrt(2 + t^2))
    assert row["diff_mean"] == pytest.approx(5 / 3)
    assert row["t_p_greater"] == pytest.approx(0.5 - 5 / (2 * math.sqrt(27)), rel=1e-9)
    assert row["wilcoxon_p_greater"] == pytest.approx(1 / 8)  # exact: 3 positive of 3
    assert row["diff_ci95"] == pytest.approx(stats.t.ppf(0.975, 2) / 3, rel=1e-12)




def test_a_delay_trained_policy_alone_has_no_paired_row() -> None:
    """Trained under a delay only (``--train bides@200ms`` in one invocation): nothing to
    pair it with yet, so no row (the runs are paired later with ``--merge``)."""
    evals = [{"trained": "bides@200ms", "seed": 0, "evaluated": "bides@200ms", "fitness": -1.8},
             {"trained": "bides@200ms", "seed": 0, "evaluated": "perfect", "fitness": -0.1}]
    assert paired_cells(evals, ["perfect", "bides@200ms"], [0]) == []


def test_control_reading_says_what_the_table_supports() -> None:
    from sigma_lab.studies.env_report import _control_reading

    table = [{"cell": "bides@200ms", "t_p_delay_beats_hidden": 0.01},
             {"cell": "none@200ms", "t_p_delay_beats_hidden": 0.2}]
    won = _control_reading(table, 5)
    assert "in bides@200ms of 2:" in won and "a learned, delay-specific advantage." in won
    lost = _control_reading([table[1]], 5)
    assert "in no cell of 1:" in lost and "**not shown**" in lost
    assert "no conclusion is drawn" in _control_reading(table, 4)  # below the protocol's 5
