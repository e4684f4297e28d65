"""What the reader decided about a log, the evidence, and the option that overrides it.

Every choice the reader makes that the file does not state outright (the layout, which
column is which, the time's unit, the acceleration's unit, whether it holds gravity) is
an :class:`Inference`. ``inspect`` lists them (text and JSON, CONTRACT.md ``inferences``)
so that a user sees what was decided and from what, and how to decide otherwise. Where
the evidence is weak the inference says so (``weak``) instead of passing a guess as fact.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Inference:
    """One decision of the reader.

    Attributes
    ----------
    what : str
        What was decided: ``"layout"``, ``"columns"``, ``"time unit"``,
        ``"acceleration unit"``, ``"gravity"``, ``"sensor limit"``, ...
    decision : str
        The decision, e.g. ``"g"``, ``"ms"``, ``"phyphox"``.
    evidence : str
        What in the file it rests on, with numbers
        (``"resting magnitude 0.998 ± 0.004, constant direction"``).
    override : str
        The option that decides otherwise (``"--accel-unit m/s^2"``); ``""`` when the
        file states it outright.
    weak : bool
        True when the evidence does not settle it: the decision is the default, and the
        user should check it.
    run : str
        The run it is about (``""`` for the whole file).
    """

    what: str
    decision: str
    evidence: str
    override: str = ""
    weak: bool = False
    run: str = ""

    @property
    def text(self) -> str:
        """One line: ``"acceleration unit: g (resting magnitude ...; override: ...)"``."""
        said = f"{self.what}: {self.decision} ({self.evidence}"
        if self.weak:
            said += "; weak evidence, check it"
        if self.override:
            said += f"; to override: {self.override}"
        return said + ")"

    def to_dict(self) -> dict[str, object]:
        """The JSON object (CONTRACT.md ``inferences``).

        Returns
        -------
        dict
            ``what``, ``decision``, ``evidence``, ``override``, ``weak``, ``run``, ``text``.
        """
        return {
            "what": self.what,
            "decision": self.decision,
            "evidence": self.evidence,
            "override": self.override,
            "weak": self.weak,
            "run": self.run,
            "text": self.text,
        }
