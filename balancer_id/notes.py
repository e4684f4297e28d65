"""Typed notes: warnings and findings with a stable code.

A :class:`Note` is what a warning or a finding is everywhere in balancer-id: a stable
``code`` that code decides on, the ``subject`` it is about (a parameter, a trial, a run,
a file, a column) and the ``text`` people read. Code never looks into the text; it asks
for the code (``note.code == "fit.at_bound"`` or :func:`has_code`). The codes are listed
in :data:`CODES` and in CONTRACT.md; the JSON carries ``notes`` as objects next to the
plain-text ``warnings`` list it always had.

A note compares equal to, and formats as, its text, so a list of notes still reads as a
list of warnings in the text output.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

Severity = Literal["warning", "info", "error"]

#: Every code a note may carry, with what it means. A new code is added here and in
#: CONTRACT.md ("Notes") in the same change; ``tests/test_notes.py`` checks both agree.
CODES: dict[str, str] = {
    # reading
    "read.gap": "dropped samples: a gap in a run's time base (never interpolated)",
    "read.time_unit": "the time column's unit was read from its header or its values",
    "read.force_unit": "the force column's name states a unit other than N: scaled to N",
    "read.rate": "the sample rate is unusual or irregular",
    "read.sensor_limit": "samples at the accelerometer's limit (clipped)",
    "read.column_guess": "a column was chosen by guess, not by its header or the column map",
    "read.gravity_header": "the header says with/without g and the data disagree",
    "read.turned_sensor": "gravity's direction changed between the resting parts of a run",
    "read.vertical_guess": "the up axis (or its sign) is a guess or a convention",
    "read.clock_restart": "the time column restarts: each stretch made a run of its own",
    "read.other": "another remark about reading the log",
    # segmenting
    "segment.run_without_trial": "a run gave no trial, with the reason",
    "segment.thrust_sign": "a given thrust's sign disagrees with the motion",
    "segment.trial_dropped": "a candidate trial was left out, with the reason",
    "segment.other": "another remark about finding the trials",
    # fitting
    "fit.at_bound": "a parameter ended at a bound the user did not set",
    "fit.not_identifiable": "a parameter is not determined by the data",
    "fit.symptom": "a parameter the data cannot determine, read as a symptom of the missing effect",
    "fit.starts_disagree": "starts of a multi-start fit ended at different optima",
    "fit.start_contradicted": "the data contradict the start (negative m_a by the paper's method)",
    "fit.below_resolution": "a time constant below what the sample rate resolves",
    "fit.correlated_residual": "standard errors widened for a residual correlated over samples",
    "fit.no_convergence": "the optimizer did not converge",
    "fit.worse_than_mean": "the fit follows the acceleration worse than its mean (fit % below 0)",
    "fit.not_reached": "a parameter the data do not reach: a bound from its profile, not a value",
    "fit.optima": "the distinct optima the starts ended at, and their costs",
    "fit.held_at_limit": "a parameter held at its physical limit (0) against the data",
    "fit.structured_residual": "the residual in motion carries more than the noise at rest",
    "fit.rest_level": "the acceleration at rest is not 0: the accelerometer's gain or zero",
    "fit.force_zero": "the force moves where its zero is read (a push, preload or tension)",
    "fit.timing": "the acceleration is early or late against its drive (late channel, dead time)",
    "fit.rival": "a model with one more library effect fits as well and moves a trusted value",
    "fit.classic_disagrees": "the paper's method disagrees with the simulation fit",
    "fit.decimated": "trials fitted at a lower rate than recorded (anti-aliased)",
    "fit.posterior_not_converged": "the posterior chain is short against its autocorrelation time",
    "fit.posterior_disagrees": "a credible interval differs from the Wald interval",
    "fit.posterior_modes": "the posterior holds other optima than the fit's (separate valleys)",
    "fit.other": "another remark about the fit",
    # diagnosing
    "diagnose.not_white": "the residual is not white beyond the sensor's noise colour",
    "diagnose.above_noise": "the residual is above the noise floor",
    "diagnose.inconsistent": "the parameters are not consistent across runs or held-out trials",
    "diagnose.ambiguous": "two explanations fit about equally well",
    "diagnose.confounded": "two explanations are confounded by how the log was recorded",
    "diagnose.sensor": "a measurement-side effect (sensor low-pass, delay, gain)",
    "diagnose.discovered": "a missing force found as a sparse sum of terms in the states",
    "diagnose.other": "another remark of the diagnosis",
    # improving
    "improve.discovered": "improve --discover wrote the discovered force as an effect file",
    "improve.no_discovery": "improve --discover found nothing to write (no file written)",
    # robot coupling
    "robot.lightly_damped": "the robot-balancer loop is lightly damped (vibrates)",
    "robot.unstable": "the robot-balancer loop is unstable",
    "robot.prediction_contradicted": "a prediction its own simulation contradicts",
    "robot.other": "another remark about the robot coupling",
    # batch and fleet
    "batch.log_failed": "a log of the batch failed",
    "batch.other": "another remark about the batch",
}


@dataclass(frozen=True)
class Note:
    """A warning or finding with a stable code.

    Parameters
    ----------
    code : str
        A key of :data:`CODES`; what code decides on.
    text : str
        The sentence people read (one line).
    subject : str or None
        What the note is about: a parameter name, ``"trial 3"``, ``"run 2"``, a file or a
        column; ``None`` when it is about the whole result.
    severity : {"warning", "info", "error"}
        ``"warning"`` unless the note is only informative.
    """

    code: str
    text: str
    subject: str | None = None
    severity: Severity = "warning"

    def __post_init__(self) -> None:
        if self.code not in CODES:
            raise ValueError(f"unknown note code {self.code!r}; add it to balancer_id.notes.CODES")

    def __str__(self) -> str:
        return self.text

    def __eq__(self, other: object) -> bool:
        if isinstance(other, str):
            return self.text == other
        if isinstance(other, Note):
            return (self.code, self.text, self.subject, self.severity) == (
                other.code,
                other.text,
                other.subject,
                other.severity,
            )
        return NotImplemented

    def __hash__(self) -> int:
        return hash(self.text)

    def __contains__(self, part: str) -> bool:  # reads like the string it replaced
        return part in self.text

    def to_dict(self) -> dict[str, str | None]:
        """The note as JSON: ``{"code", "subject", "severity", "text"}``."""
        return {
            "code": self.code,
            "subject": self.subject,
            "severity": self.severity,
            "text": self.text,
        }

    @classmethod
    def from_dict(cls, data: dict) -> Note:
        """Rebuild a note from :meth:`to_dict`'s output.

        Parameters
        ----------
        data : dict
            ``{"code", "text"}`` and optionally ``"subject"``, ``"severity"``.

        Returns
        -------
        Note
            The note.
        """
        return cls(
            code=str(data["code"]),
            text=str(data["text"]),
            subject=data.get("subject"),
            severity=data.get("severity", "warning"),
        )


def as_note(item: Note | str, default_code: str = "fit.other") -> Note:
    """A note from a note or a plain string.

    Parameters
    ----------
    item : Note or str
        A note (returned as is) or a sentence.
    default_code : str
        The code a plain sentence gets.

    Returns
    -------
    Note
        The note.
    """
    if isinstance(item, Note):
        return item
    return Note(default_code, " ".join(str(item).split()))


def has_code(notes: Iterable[Note | str], code: str, subject: str | None = None) -> bool:
    """Whether any note carries ``code`` (and ``subject``, when given).

    Parameters
    ----------
    notes : iterable of Note or str
        Notes (plain strings carry no code and never match).
    code : str
        The code to look for.
    subject : str, optional
        Only a note about this subject matches.

    Returns
    -------
    bool
        True when one matches.
    """
    for item in notes:
        if isinstance(item, Note) and item.code == code:
            if subject is None or item.subject == subject:
                return True
    return False


def texts(notes: Iterable[Note | str]) -> list[str]:
    """The notes' texts, in order (the JSON ``warnings`` list).

    Parameters
    ----------
    notes : iterable of Note or str
        Notes or sentences.

    Returns
    -------
    list of str
        Their texts.
    """
    return [str(n) for n in notes]


def notes_json(notes: Iterable[Note | str], default_code: str = "fit.other") -> list[dict]:
    """The notes as JSON objects (the JSON ``notes`` list).

    Parameters
    ----------
    notes : iterable of Note or str
        Notes or sentences.
    default_code : str
        The code a plain sentence gets.

    Returns
    -------
    list of dict
        One :meth:`Note.to_dict` per note.
    """
    return [as_note(n, default_code).to_dict() for n in notes]
