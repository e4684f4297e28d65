"""Typed notes: stable codes, listed in CONTRACT.md, compared by code not wording."""

from pathlib import Path

import pytest

from balancer_id.notes import CODES, Note, as_note, has_code, notes_json, texts

CONTRACT = Path(__file__).resolve().parents[1] / "docs" / "CONTRACT.md"


def test_every_code_is_listed_in_the_contract() -> None:
    text = CONTRACT.read_text(encoding="utf-8")
    missing = [code for code in CODES if f"`{code}`" not in text]
    assert missing == []


def test_an_unknown_code_is_refused() -> None:
    with pytest.raises(ValueError, match=r"unknown note code 'fit\.nonsense'"):
        Note("fit.nonsense", "x")


def test_a_note_reads_as_its_text_and_is_found_by_code() -> None:
    note = Note("fit.at_bound", "m_a ended at its upper bound 500 kg", subject="m_a")
    assert str(note) == "m_a ended at its upper bound 500 kg"
    assert note == "m_a ended at its upper bound 500 kg"
    assert has_code([note, "plain"], "fit.at_bound", subject="m_a")
    assert not has_code([note], "fit.at_bound", subject="T_a")
    assert texts([note, "plain"]) == [note.text, "plain"]
    (obj,) = notes_json([note])
    assert obj == {"code": "fit.at_bound", "subject": "m_a", "severity": "warning",
                   "text": note.text}
    assert Note.from_dict(obj) == note
    assert as_note("  two   spaces ").text == "two spaces"
