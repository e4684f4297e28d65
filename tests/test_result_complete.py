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
    result.advice = None  # the one field attached later (the robot advice)


def test_per_trial_fits_of_a_result_made_without_them_are_a_cache():
    result = fit(SAMPLE_LOGS / "paper_balancer.csv")
    assert "per_trial" not in result.to_dict()
    first = result.per_trial_fits()
    assert len(first) == len(result.match.data.trials)
    assert result.per_trial_fits() is first  # computed once
    assert "per_trial" not in result.to_dict()  # shown only when asked for at the fit
