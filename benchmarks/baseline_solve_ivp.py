"""The script a user would otherwise write: solve_ivp inside lmfit (the speed baseline).

Reads and segments a log with balancer-id (so both sides fit the same trials), then fits
``variable_viscosity`` (m_a, T_a, D0, A) to all trials at once with lmfit's
``least_squares`` around ``scipy.integrate.solve_ivp`` (DOP853, max_step 0.01 s, the
thrust's steps as integration edges) and prints the values. Compare a whole command with
it, in the same run::

    /usr/bin/time -v python benchmarks/baseline_solve_ivp.py LOG.csv
    /usr/bin/time -v balancer-id fit LOG.csv --no-cache --json

``--core`` prints the time of the fit alone (the trials already in memory).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import lmfit
import numpy as np

from balancer_id.identify.api import trial_data
from balancer_id.model import parse_model
from balancer_id.trials import load_trials

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the tests' simlib

from simlib.reference import simulate_reference


def fit_script(trials, start=None) -> lmfit.minimizer.MinimizerResult:
    """Fit variable_viscosity to ``trials`` with solve_ivp inside lmfit.

    Parameters
    ----------
    trials : list of TrialData
        The trials.
    start : dict, optional
        Start values (default ``m_a = 15``, ``T_a = 0.3``).

    Returns
    -------
    lmfit.minimizer.MinimizerResult
    """
    model = parse_model("variable_viscosity")
    params = model.lmfit_parameters(start or {"m_a": 15.0, "T_a": 0.3})

    def residual(p):
        vals = p.valuesdict()
        return np.concatenate(
            [
                simulate_reference(model, vals, td.input, max_step=0.01).accel - td.accel
                for td in trials
            ]
        )

    return lmfit.minimize(residual, params, method="least_squares", x_scale="jac")


def main() -> None:
    """Fit the log given on the command line; print the values (and the core time)."""
    trials = trial_data(load_trials([sys.argv[1]]))
    t0 = time.perf_counter()
    out = fit_script(trials)
    core = time.perf_counter() - t0
    print({k: round(p.value, 5) for k, p in out.params.items()})
    if "--core" in sys.argv:
        print(f"core fit: {core:.2f} s")


if __name__ == "__main__":
    main()
