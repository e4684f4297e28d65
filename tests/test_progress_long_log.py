"""A long log says how far its reading and segmentation are (issue 21: a 1.5 GB log
showed nothing for minutes). The library tells; the command line shows it on a terminal."""

from __future__ import annotations

from pathlib import Path

import balancer_id.read.sniff as sniff
import balancer_id.read.table as table
from balancer_id.status import listening
from balancer_id.trials import read, segment

SAMPLE = Path(__file__).resolve().parents[1] / "sample_logs" / "paper_balancer.csv"


def test_reading_and_segmenting_tell_how_far_they_are(monkeypatch):
    # the sample read as a long log is: streamed from disk, in chunks of 500 rows
    monkeypatch.setattr(sniff, "HEAD_BYTES", 4096)
    monkeypatch.setattr(table, "CHUNK_ROWS", 500)
    told: list[str] = []
    with listening(told.append):
        trials = segment(read(SAMPLE))
    assert trials
    shares = [t for t in told if t.startswith("reading rows: ")]
    assert len(shares) >= 3 and shares[0].startswith("reading rows: 0% of ~")
    assert any(t.startswith("finding the trials of run 1/") for t in told)
    assert any(t.endswith(", the force steps") for t in told)
    assert any(t.endswith(", the trials' windows") for t in told)


def test_a_short_log_reads_without_a_word():
    told: list[str] = []
    with listening(told.append):
        read(SAMPLE)
    assert not [t for t in told if t.startswith("reading rows")]
