"""What a batch's fork server loads before it forks the workers (balancer_id.batch.preload)."""

from __future__ import annotations

import os

import pytest

from balancer_id.batch.preload import ENV, preload
from balancer_id.model import parse_model
from balancer_id.simulation import kernel


def _loaded_in_worker(_: int) -> tuple[bool, bool, bool]:
    """In a pool worker: is the default model's kernel loaded, the fit imported, gc on?"""
    import gc
    import sys

    from balancer_id.simulation import kernel as k

    mdl = parse_model("variable_viscosity")
    loaded = (mdl.effects, mdl.param_names) in k._KERNELS
    return loaded, "balancer_id.identify.api" in sys.modules, gc.isenabled()


def test_preload_loads_the_models_and_skips_what_it_cannot(monkeypatch) -> None:
    monkeypatch.setattr(kernel, "_KERNELS", {})
    preload(["viscous", "no_such_effect", "viscous+variable_viscosity"])  # bad specs: skipped
    mdl = parse_model("viscous")
    assert list(kernel._KERNELS) == [(mdl.effects, mdl.param_names)]


def test_preload_with_diagnose_loads_the_candidates_too(monkeypatch) -> None:
    from balancer_id.diagnostics.candidates import candidates

    monkeypatch.setattr(kernel, "_KERNELS", {})
    preload(["variable_viscosity"], diagnose=True)
    mdl = parse_model("variable_viscosity")
    wanted = {(c.model.effects, c.model.param_names) for c in candidates(mdl)}
    assert wanted
    assert wanted | {(mdl.effects, mdl.param_names)} == set(kernel._KERNELS)


_SCRIPT = """
import os, sys
from concurrent.futures import ProcessPoolExecutor
from balancer_id.batch.executors import _mp_context
from balancer_id.batch.preload import ENV
from test_batch_preload import _loaded_in_worker

if __name__ == "__main__":
    ctx = _mp_context(["variable_viscosity"])
    assert ENV not in os.environ  # only the server saw the request
    with ProcessPoolExecutor(1, mp_context=ctx) as pool:
        print(*pool.submit(_loaded_in_worker, 0).result())
"""


def test_workers_are_forked_with_the_kernel_loaded(tmp_path) -> None:
    """A fresh process (a fork server started earlier in this session keeps its load)."""
    import multiprocessing
    import subprocess
    import sys
    from pathlib import Path

    if "forkserver" not in multiprocessing.get_all_start_methods():
        pytest.skip("no forkserver on this platform")
    script = tmp_path / "run.py"
    script.write_text(_SCRIPT)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parent)}
    env.pop(ENV, None)
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, env=env, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True", "True"]
