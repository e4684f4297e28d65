"""Workflows held by the library: ``bid.full_report`` is what ``balancer-id report`` runs."""

from __future__ import annotations

import pytest
from conftest import SAMPLE_LOGS

import balancer_id as bid
from balancer_id.errors import UsageError

LOG = SAMPLE_LOGS / "paper_balancer.csv"


def test_report_is_one_library_call(tmp_path):
    out = tmp_path / "report.html"
    done = bid.full_report(LOG, out, model="variable_viscosity")
    assert done.path == out and out.is_file()
    text = out.read_text(encoding="utf-8")
    assert done.diagnosis.verdict in text  # what it computed is what it wrote
    assert done.fit.include_per_trial and done.fit.per_trial
    assert done.improved.steps


def test_report_never_writes_over_an_input(tmp_path):
    log = tmp_path / "log.csv"
    log.write_bytes(LOG.read_bytes())
    with pytest.raises(UsageError, match="one of the inputs"):
        bid.full_report(log, log, overwrite=True)
    assert log.read_bytes() == LOG.read_bytes()
