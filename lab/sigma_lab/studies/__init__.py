"""The paper studies' shared code: run many scenarios, derive, aggregate, write, plot.

The scripts in ``experiments/`` hold only their scenarios and plots; everything they
share lives here:

* :mod:`~sigma_lab.studies.args` — the common command line (``--quick``, ``--seeds``…);
* :mod:`~sigma_lab.studies.model` — :class:`MethodSpec`, :class:`RunRecord`, :class:`Study`;
* :mod:`~sigma_lab.studies.run` — :func:`run_study` on the local executor
  (:mod:`sigma_des.pool`);
* :mod:`~sigma_lab.studies.derived` — metrics derived from the render-tick series;
* :mod:`~sigma_lab.studies.output` — ``results.csv``, ``timeseries.csv``, ``summary.json``;
* :mod:`~sigma_lab.studies.plots` — colours, bars, AoI panels (matplotlib, Agg);
* :mod:`~sigma_lab.studies.tables` — the one table formatter (text and Markdown).
* :mod:`~sigma_lab.studies.delay` — the delay study's conditions and paired statistics.
* :mod:`~sigma_lab.studies.delay_study` — the delay study's runs, outputs and shard merge.
"""

from sigma_lab.studies.args import (
    command_line,
    finish_args,
    parse_args,
    parse_seeds,
    study_parser,
)
from sigma_lab.studies.derived import DERIVED_UNITS, derived_metrics, seed_means, window_stats
from sigma_lab.studies.model import MethodSpec, RunRecord, Study
from sigma_lab.studies.output import (
    CSV_COLUMNS,
    TS_KEYS,
    aggregate,
    finish,
    json_ready,
    tidy_rows,
    update_plot_list,
    write_rows,
    write_study,
    write_summary,
)
from sigma_lab.studies.plots import (
    COLORS,
    bar_metric,
    bar_panels,
    legend_outside,
    line_kw,
    moving_average,
    plot_aoi_dist,
    plot_aoi_time,
    plot_lines,
    plot_rate,
    plot_setup,
    rate_ylim,
    save,
)
from sigma_lab.studies.run import known, load_scenario, run_case, run_study, scenario_for
from sigma_lab.studies.tables import md_table, text_table, variant_table

__all__ = [
    "COLORS",
    "CSV_COLUMNS",
    "DERIVED_UNITS",
    "MethodSpec",
    "RunRecord",
    "Study",
    "TS_KEYS",
    "aggregate",
    "bar_metric",
    "bar_panels",
    "command_line",
    "derived_metrics",
    "finish",
    "finish_args",
    "json_ready",
    "known",
    "legend_outside",
    "line_kw",
    "load_scenario",
    "md_table",
    "moving_average",
    "parse_args",
    "parse_seeds",
    "plot_aoi_dist",
    "plot_aoi_time",
    "plot_lines",
    "plot_rate",
    "plot_setup",
    "rate_ylim",
    "run_case",
    "run_study",
    "save",
    "scenario_for",
    "seed_means",
    "study_parser",
    "text_table",
    "tidy_rows",
    "update_plot_list",
    "variant_table",
    "window_stats",
    "write_rows",
    "write_study",
    "write_summary",
]
