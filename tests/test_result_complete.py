"""A FitResult is complete when returned and immutable afterwards (issue 20.1)."""

from __future__ import annotations

import dataclasses

import pytest
from conftest import SAMPLE_LOGS

from balancer_id.identify import fit
from balancer_id.notes import Note


def test_a_fit_result_is_complete_when_returned_and_immutable():
    result = fit(SAMPLE_LOGS / "paper_balancer.csv", per_trial=True)
    # the per-trial fits and the notes were computed by the call that returned it
    assert result.include_per_trial and len(result.per_trial) == len(result.match.data.trials)
    data = result.to_dict()
    assert len(data["per_trial"]) == len(data["trials"])
    assert all(isinstance(w, Note) for w in result.warnings)
    assert set(data["warnings"]) <= {n["text"] for n in data["notes"]}
    for name, value in [("warnings", []), ("include_per_trial", False), ("fixed", {})]:
        with pytest.raises(dataclasses.FrozenInstanceError, match=name):
            setattr(result, name, value)
    assert result.to_dict() == data  # nothing changed it
    with pytest.raises(AttributeError):
        result.advice = None  # derived from the fit (a robot pair's advice), never set
    assert result.advice is None  # no robot in this model


def test_per_trial_fits_of_a_result_made_without_them_are_a_cache():
    result = fit(SAMPLE_LOGS / "paper_balancer.csv")
    assert "per_trial" not in result.to_dict()
    first = result.per_trial_fits()
    assert len(first) == len(result.match.data.trials)
    assert result.per_trial_fits() is first  # computed once
    assert "per_trial" not in result.to_dict()  # shown only when asked for at the fit


ROBOT_MOVE = "trapezoid:distance=0.2,speed=0.1,accel=0.5"


@pytest.mark.parametrize(
    ("log", "extra"),
    [
        ("paper_balancer.csv", {"model": "viscous"}),
        (
            "robot/robot_assist.csv",
            {"model": "variable_viscosity+servo", "trajectory": ROBOT_MOVE},
        ),
    ],
)
def test_the_library_result_is_the_commands_json(cli, log, extra):
    """``bid.fit(...).to_dict()`` equals ``fit --json`` (the robot's advice included)."""
    import json

    path = SAMPLE_LOGS / log
    data = fit(path, **extra).to_dict()
    args = [a for k, v in extra.items() for a in (f"--{k}", v)]
    code, out, err = cli("fit", path, *args, "--json")
    # 5: a fit that is not trusted (the robot's log alone leaves A to a guess) prints the
    # same JSON, and says why
    assert code == (0 if data["trusted"] else 5), err
    assert json.loads(out) == json.loads(json.dumps(data))
    if "trajectory" in extra:
        assert data["advice"]["settings"]  # computed by the library call, not the command
