"""Shared fixtures: paths, seeded synthetic trials, the CLI runner."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
REAL_LOGS = SHARED / "real_logs"
EXAMPLES = REPO / "examples"
SAMPLE_LOGS = REPO / "sample_logs"

#: The paper's balancer (MODEL.md reference values).
PAPER = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
PAPER_THRUSTS = (2.45, -2.45, 4.9, -4.9, 7.35, -7.35)


@pytest.fixture(scope="session", autouse=True)
def _kernels_compiled_once():
    """The kernels most tests use, compiled before the first test, once per session.

    Missing ones go into the disk cache at once, in several processes, and once for all
    xdist workers (the others wait on the cache's lock, then find them): no test pays
    for a compilation that another worker is doing too.
    """
    from balancer_id.diagnostics.candidates import candidates
    from balancer_id.model import parse_model
    from balancer_id.simulation.kernel import compile_models

    models = []
    for spec in ("variable_viscosity", "viscous"):
        model = parse_model(spec)
        models += [model, *(c.model for c in candidates(model))]
    compile_models(models)


@pytest.fixture(autouse=True)
def _no_result_cache(monkeypatch):
    """Commands compute their results in tests (the result cache has its own test)."""
    monkeypatch.setenv("BALANCER_ID_NO_CACHE", "1")


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator, fresh for each test."""
    return np.random.default_rng(20261122)


@pytest.fixture
def cli():
    """Run the installed command's typer app in-process; returns (exit code, stdout, stderr)."""
    from typer.testing import CliRunner

    from balancer_id.cli import app

    runner = CliRunner()

    def run(*args: str) -> tuple[int, str, str]:
        res = runner.invoke(app, [str(a) for a in args])
        return res.exit_code, res.stdout, res.stderr

    return run
