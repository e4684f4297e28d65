"""Results read back (issue 30.3): ``X.from_dict(x.to_dict())`` is a frozen record whose
JSON equals ``x.to_dict()`` and which renders exactly as ``x`` did; the result cache
serves the same object a fresh fit returns."""

from __future__ import annotations

import dataclasses
import io
import json

import pytest
from conftest import SAMPLE_LOGS
from hypothesis import given, settings
from hypothesis import strategies as st
from rich.console import Console

from balancer_id.records import FitRecord, ResultRecord, freeze, thaw

JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda children: st.lists(children, max_size=4)
    | st.dictionaries(st.text(max_size=6), children, max_size=4),
    max_leaves=20,
)


@settings(max_examples=60, deadline=None)
@given(st.dictionaries(st.text(max_size=6), JSON, max_size=6))
def test_any_json_object_reads_back_equal_and_frozen(data):
    record = ResultRecord.from_dict(data)
    assert record.to_dict() == data
    assert record == ResultRecord.from_dict(json.loads(json.dumps(data)))
    assert thaw(freeze(data)) == data
    copy = record.to_dict()
    # a key longer than any drawn (6 characters): never one of the data's own
    copy["added by caller"] = 1  # the JSON handed out is the caller's own
    assert "added by caller" not in record.data
    with pytest.raises(TypeError):
        record.data["added by caller"] = 1  # type: ignore[index]
    with pytest.raises(dataclasses.FrozenInstanceError):
        record.data = {}  # type: ignore[misc]


def _terminal(printer: str, data: dict) -> str:
    from balancer_id.report import terminal

    console = Console(file=io.StringIO(), width=120, color_system=None)
    getattr(terminal, printer)(console, data)
    return console.file.getvalue()  # type: ignore[attr-defined]


@pytest.fixture(scope="module")
def fitted():
    from balancer_id.identify import fit

    return fit(SAMPLE_LOGS / "paper_balancer.csv", model="viscous")


def test_a_fit_reads_back_and_renders_as_it_did(fitted):
    from balancer_id.identify.result import FitResult

    data = fitted.to_dict()
    back = FitResult.from_dict(data)
    assert isinstance(back, FitRecord)
    assert back.to_dict() == data
    # through a file (the cache, --save): the same record
    assert FitResult.from_dict(json.loads(json.dumps(data))) == back
    assert back.model == fitted.model and back.values == pytest.approx(fitted.values)
    assert back.trusted == fitted.trusted
    assert [n.code for n in back.notes] == [n["code"] for n in data["notes"]]
    assert _terminal(back.printer, back.to_dict()) == _terminal("print_fit", data)


@pytest.fixture(scope="module")
def diagnosed(fitted):
    from balancer_id.diagnostics.diagnosis import diagnose

    return diagnose(fitted, discover=False)


def test_a_diagnosis_reads_back_and_renders_as_it_did(diagnosed):
    from balancer_id.diagnostics.diagnosis import Diagnosis

    diagnosis = diagnosed
    data = diagnosis.to_dict()
    back = Diagnosis.from_dict(json.loads(json.dumps(data)))
    assert back.to_dict() == data and back.verdict == diagnosis.verdict
    assert _terminal(back.printer, back.to_dict()) == _terminal("print_diagnosis", data)


def test_a_cached_fit_is_the_object_a_fresh_fit_gives(tmp_path, monkeypatch):
    from balancer_id.workflows.fit_logs import FitJob
    from balancer_id.workflows.request import FitRequest

    monkeypatch.setenv("BALANCER_ID_NO_CACHE", "0")
    monkeypatch.setenv("BALANCER_ID_CACHE", str(tmp_path))
    job = FitJob(FitRequest((str(SAMPLE_LOGS / "paper_balancer.csv"),), model="viscous"))
    fresh = job.run()
    assert list((tmp_path / "results").glob("*.json")), "the fit was not cached"
    cached = job.run()
    assert isinstance(fresh.result, FitRecord) and isinstance(cached.result, FitRecord)
    assert cached.result == fresh.result
    assert cached.out == fresh.out and cached.trusted == fresh.trusted


def test_a_fit_result_cannot_be_changed_in_place(fitted):
    """Deep enough: no field of the fit or of its match can be set, and their tables and
    lists are read-only (the checks annotate a match before the fit seals it)."""
    before = fitted.to_dict()
    with pytest.raises(dataclasses.FrozenInstanceError, match="nfev"):
        fitted.match.nfev = 0
    for table in (fitted.fixed, fitted.match.metrics, fitted.match.parameters):
        with pytest.raises(TypeError):
            table["added"] = 1
    for seq in (fitted.warnings, fitted.match.warnings, fitted.effects_files):
        with pytest.raises(AttributeError):
            seq.append("added")
    assert fitted.to_dict() == before


def test_a_new_field_of_the_diagnosis_is_one_line_of_the_field_list(diagnosed, monkeypatch):
    """Traced change (issue 30): a field added to DIAGNOSIS_FIELDS (beside its dataclass
    line) shows in the JSON, the terminal, the notebook and the report, with no renderer
    edited."""
    from balancer_id import diagnosis_fields
    from balancer_id.diagnosis_fields import DiagnosisField
    from balancer_id.diagnostics import diagnosis as diagnosis_module
    from balancer_id.report.blocks import Paragraph
    from balancer_id.report.sections import diagnosis_section

    before = _terminal("print_diagnosis", diagnosed.to_dict())
    new = DiagnosisField(
        "excess_share",
        lambda d: d.context.excess_rmse() / d.match.metrics["rmse"],
        line=lambda v: f"share of the error above the noise floor: {v:.1%}",
    )
    fields = (*diagnosis_fields.DIAGNOSIS_FIELDS, new)
    monkeypatch.setattr(diagnosis_fields, "DIAGNOSIS_FIELDS", fields)
    monkeypatch.setattr(diagnosis_module, "DIAGNOSIS_FIELDS", fields)
    data = diagnosed.to_dict()
    share = diagnosed.context.excess_rmse() / diagnosed.match.metrics["rmse"]
    assert data["excess_share"] == pytest.approx(share)
    line = f"share of the error above the noise floor: {share:.1%}"
    shown = _terminal("print_diagnosis", data)
    assert line in shown and line not in before
    assert line in diagnosed.summary()
    section = diagnosis_section(diagnosed)
    assert any(isinstance(b, Paragraph) and b.text == line for b in section.blocks)


def test_a_comparison_reads_back_and_renders_as_it_did():
    from balancer_id.jsonsafe import json_ready
    from balancer_id.records import ComparisonRecord
    from balancer_id.workflows.compare_logs import CompareRun, compare_logs

    run = compare_logs([SAMPLE_LOGS / "paper_balancer.csv"], "viscous")
    data = json_ready(run.to_dict())
    back = CompareRun.from_dict(json.loads(json.dumps(data)))
    assert isinstance(back, ComparisonRecord) and back.models == ["viscous"]
    assert back.to_dict() == data
    assert _terminal(back.printer, back.to_dict()) == _terminal("print_compare", run.to_dict())


def test_a_sealed_fit_s_estimates_cannot_be_changed(fitted):
    name, estimate = next(iter(fitted.match.parameters.items()))
    with pytest.raises(dataclasses.FrozenInstanceError, match="stderr"):
        estimate.stderr = 0.0
    with pytest.raises(AttributeError):
        estimate.distrust.append("added")  # a tuple once sealed
    assert fitted.to_dict()["parameters"][name]["value"] == estimate.value
