"""A fit's error metrics are listed once (metric_fields.FIT_METRICS): a new one shows in
the JSON, the notebook text and HTML, the terminal and the HTML report."""

from __future__ import annotations

import dataclasses
import io
from pathlib import Path

import pytest
from rich.console import Console

import balancer_id as bid
from balancer_id import metric_fields
from balancer_id.metric_fields import FIT_METRICS, MetricField, metric_line
from balancer_id.report.document import write_fit_report
from balancer_id.report.terminal import print_fit

SAMPLE = Path(__file__).resolve().parents[1] / "sample_logs" / "paper_balancer.csv"


@pytest.fixture(scope="module")
def result():
    return bid.fit(SAMPLE)


def test_every_metric_the_fit_computes_is_listed_and_formatted(result):
    keys = {f.key for f in FIT_METRICS}
    assert keys == set(result.metrics)
    line = metric_line(result.metrics)
    assert line.startswith("RMSE = ") and "m/s²" in line and "samples = " in line
    assert f"BIC = {result.metrics['bic']:.1f}" in line
    assert MetricField("x", "x").format(None) == "-"


def test_a_new_metric_is_shown_by_every_renderer(result, tmp_path, monkeypatch):
    extra = MetricField("durbin_watson", "Durbin-Watson", digits=3)
    monkeypatch.setattr(metric_fields, "FIT_METRICS", (*FIT_METRICS, extra))
    # a fit is complete when made: the new metric comes with a fit made with it
    metrics = {**result.match.metrics, "durbin_watson": 1.23456}
    result = dataclasses.replace(result, match=dataclasses.replace(result.match, metrics=metrics))
    shown = "Durbin-Watson"
    assert result.to_dict()["metrics"]["durbin_watson"] == 1.23456  # JSON
    assert f"{shown:<18} = 1.23" in result.summary()  # notebook text
    assert f"{shown} = 1.23" in result._repr_html_()  # notebook HTML
    out = io.StringIO()
    print_fit(Console(file=out, width=200), result.to_dict())
    assert f"{shown} = 1.23" in out.getvalue()  # terminal
    html = write_fit_report(result, tmp_path / "fit.html").read_text(encoding="utf-8")
    assert f"<th>{shown}</th>" in html and "1.23" in html  # report
