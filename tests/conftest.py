"""Shared fixtures: paths, seeded synthetic trials, the CLI runner."""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

# Models of built-in effects run on the shared kernels (the default, stated here so that
# a user's own setting does not change what the tests run); test_shared_kernel.py checks
# them against each model's own kernel.
os.environ["BALANCER_ID_KERNELS"] = "shared"

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
REAL_LOGS = SHARED / "real_logs"
EXAMPLES = REPO / "examples"
SAMPLE_LOGS = REPO / "sample_logs"

#: The paper's balancer (MODEL.md reference values).
PAPER = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
PAPER_THRUSTS = (2.45, -2.45, 4.9, -4.9, 7.35, -7.35)


def _shared_fixture_modules() -> set[str]:
    """The test modules defining a module-scoped fixture (a costly fit, the README's work
    folder whose commands build on each other)."""
    here = Path(__file__).parent
    return {
        p.name for p in here.glob("test_*.py") if 'scope="module"' in p.read_text("utf-8")
    }


def _unit(nodeid: str, shared: set[str]) -> str:
    """The unit of work ``nodeid`` is handed out in: its module when the module has a
    module-scoped fixture (built once, on one worker), else the test alone."""
    module = nodeid.split("::")[0]
    return module if Path(module).name in shared else nodeid


@pytest.hookimpl(tryfirst=True, optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """Under ``-n`` (xdist's ``--dist load``): each test goes to whichever worker is free,
    except that a module with a module-scoped fixture goes whole to one worker, so its
    fixture is built once (xdist's ``load`` hands out runs of consecutive tests, which
    split such a module, the README's commands included, across both workers: each built
    the fixture, and ran the README's earlier commands again). The units go out in the
    order of pytest_collection_modifyitems below: slow ones first."""
    if config.getoption("dist") != "load":
        return None  # a --dist the user chose
    from xdist.scheduler import LoadScopeScheduling

    shared = _shared_fixture_modules()

    class SharedFixtureScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return _unit(nodeid, shared)

    config.option.loadscopereorder = False  # in collection order, not largest unit first
    return SharedFixtureScheduling(config, log)


def _needs_real_logs(item) -> bool:
    """Whether ``item`` reads the public exports of ``../shared/real_logs``."""
    if item.get_closest_marker("needs_real_logs"):
        return True
    return any("real_logs" in str(m.kwargs.get("reason", "")) for m in item.iter_markers("skipif"))


#: Tests left out because ``../shared/real_logs`` is not beside this checkout.
_WITHOUT_REAL_LOGS: list[str] = []


def pytest_collection_modifyitems(config, items):
    """The units (see pytest_xdist_make_scheduler) holding tests marked ``slow`` first, the
    one with the most of them first (the README's commands), so that none of them is the
    run's tail while the other worker idles; otherwise as collected. A unit stays whole.

    Without ``../shared/real_logs`` (a checkout outside this repository's layout) the
    tests that read it are deselected and said once in the summary, not skipped one by
    one."""
    if not REAL_LOGS.is_dir():
        absent = [item for item in items if _needs_real_logs(item)]
        if absent:
            _WITHOUT_REAL_LOGS[:] = [item.nodeid for item in absent]
            config.hook.pytest_deselected(items=absent)
            items[:] = [item for item in items if item not in set(absent)]
    shared = _shared_fixture_modules()
    units = {item: _unit(item.nodeid, shared) for item in items}
    slow = Counter(units[item] for item in items if item.get_closest_marker("slow"))
    items.sort(key=lambda item: -slow[units[item]])


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """One line for the tests that need ``../shared/real_logs`` when it is absent."""
    if _WITHOUT_REAL_LOGS:
        terminalreporter.write_line(
            f"{len(_WITHOUT_REAL_LOGS)} tests read the public exports in {REAL_LOGS}, "
            "which is not beside this checkout: not run (clone the project with its "
            "shared/ folder to run them)"
        )


@pytest.fixture(scope="session", autouse=True)
def _kernels_compiled_once():
    """The kernels most tests use (the shared kernels of the built-in effects), compiled
    before the first test, once per session.

    Missing ones go into the disk cache at once, in several processes, and once for all
    xdist workers (the others wait on the cache's lock, then find them): no test pays
    for a compilation that another worker is doing too.
    """
    from balancer_id.diagnostics.candidates import candidates
    from balancer_id.model import parse_model
    from balancer_id.simulation.kernel_compile import compile_models

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


@pytest.fixture
def results_cache(tmp_path, monkeypatch):
    """A result cache of this test's own (``tmp_path/results``), switched on, beside a copy
    of the run's compiled kernels: an empty cache folder compiled every kernel again (20 s
    a test warm), and a link to the run's is refused by the kernel cache."""
    import shutil

    from balancer_id.files import cache_root

    shared = cache_root()
    for folder in ("kernels", "numba"):
        if (shared / folder).is_dir():
            shutil.copytree(shared / folder, tmp_path / folder, copy_function=shutil.copy2)
    monkeypatch.setenv("BALANCER_ID_NO_CACHE", "0")
    monkeypatch.setenv("BALANCER_ID_CACHE", str(tmp_path))
    return tmp_path
