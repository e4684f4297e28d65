"""``trusted`` is a claim (issue 31): never true when the fit's own notes say a parameter is
not determined, and visible to scripts as exit 5."""

from __future__ import annotations

import json
import subprocess
import sys

from conftest import SAMPLE_LOGS

from balancer_id.errors import UNTRUSTED_EXIT_CODE


def _fit_json(*args: object) -> tuple[int, dict]:
    proc = subprocess.run(
        [sys.executable, "-m", "balancer_id", "fit", *map(str, args), "--json", "--no-cache"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert "Traceback" not in proc.stderr
    return proc.returncode, json.loads(proc.stdout)


def test_undetermined_parameter_is_untrusted_with_exit_5() -> None:
    # a hose's pull the model lacks: m_a, T_a and A trade and are not determined
    code, out = _fit_json(SAMPLE_LOGS / "hose_walkthrough.csv")
    assert out["trusted"] is False
    assert code == UNTRUSTED_EXIT_CODE == 5
    assert any("cannot determine" in why for why in out["untrusted_because"])
    # the reason leads the warnings
    assert out["warnings"][0] == out["untrusted_because"][0]


def test_identified_fit_is_trusted_with_exit_0() -> None:
    code, out = _fit_json(SAMPLE_LOGS / "paper_balancer.csv")
    assert code == 0
    assert out["trusted"] is True and out["untrusted_because"] == []
