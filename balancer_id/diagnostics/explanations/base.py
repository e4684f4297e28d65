"""What every explanation is: a fitted model of what the current one misses, and its kind.

An :class:`Explanation` is one fitted alternative (its label, its BIC fall, its detail);
an :class:`ExplanationKind` is how such alternatives are proposed, fitted and scored
(:meth:`ExplanationKind.propose`), named (:meth:`ExplanationKind.sentence`), which
verdict they lead to, what they mimic and the trial that separates them. The kinds are
listed once, in :data:`balancer_id.diagnostics.explanations.KINDS`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum
from typing import TYPE_CHECKING, Any, ClassVar

from balancer_id.verdicts import Verdict

if TYPE_CHECKING:
    from balancer_id.identify.result import FitResult


class Stage(IntEnum):
    """When a kind's explanations are fitted in the arena.

    ``FIRST``: from the current fit alone; ``PAIRED``: on top of the best library effect
    of the first stage; ``LAST``: after both, when the verdict's tests still fail
    (the discovered force).
    """

    FIRST = 0
    PAIRED = 1
    LAST = 2


@dataclass
class Explanation:
    """One fitted explanation of what the current model misses.

    Attributes
    ----------
    kind : str
        The CONTRACT.md ``kind``: ``effect``, ``split``, ``drift``, ``trend``,
        ``sensor``, ``pair`` or ``discovered``.
    label : str
        Short name (``+karnopp``, ``m_a changes after run 3``, ``D0 drifting over the
        runs``, ``sensor low-pass at 6.1 Hz``).
    delta_bic : float
        Fall of BIC against the current fit, scaled by the share of independent samples
        (positive: better).
    rmse : float
        RMSE of its fit (m/s^2).
    effects : list of str
        Library effects it adds.
    parameters : list of str
        Parameters it lets change (split, drift, trend).
    detail : dict
        Its fitted values (``before``/``after``, ``start``/``end``, ``cutoff_hz`` ...).
    excess_drop : float
        Share of the error above the noise floor it removes.
    null : bool
        Its added parameter sits at the value that does nothing (dead time 0, friction 0):
        no benefit, never a verdict nor a step of ``improve``.
    share : float or None
        Share of the BIC fall a perfect model would bring (:meth:`ArenaInput.available`).
    refine : callable or None
        Refits it from where it ended with more iterations (the arena's fits are capped
        for speed); None when it cannot be refined. Returns the refined explanation.
    key : str
        The registry key of its :class:`ExplanationKind` (``sensor_gain``); empty: the
        kind of the same name as :attr:`kind`.
    """

    kind: str
    label: str
    delta_bic: float
    rmse: float
    effects: list[str] = field(default_factory=list)
    parameters: list[str] = field(default_factory=list)
    detail: dict[str, object] = field(default_factory=dict)
    excess_drop: float = 0.0
    null: bool = False
    share: float | None = None
    refine: Callable[[], Explanation] | None = field(default=None, repr=False, compare=False)
    key: str = ""
    #: The object it was fitted as, when it has one (a discovery's :class:`Discovery`).
    source: object = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not self.key:
            self.key = self.kind

    @property
    def explainer(self) -> ExplanationKind:
        """Its kind, from the registry."""
        return kind_of(self.key)

    @property
    def verdict(self) -> Verdict:
        """The verdict this explanation leads to."""
        return self.explainer.verdict_of(self)

    def to_dict(self) -> dict[str, object]:
        """CONTRACT.md ``diagnose`` ``explanations`` record."""
        return {
            "kind": self.kind,
            "label": self.label,
            "verdict": str(self.verdict),
            "delta_bic": self.delta_bic,
            "rmse_after": self.rmse,
            "excess_error_drop": self.excess_drop,
            "share_of_excess": self.share,
            "effects": list(self.effects),
            "parameters": list(self.parameters),
            "detail": self.detail,
        }


class ExplanationKind:
    """One kind of explanation: how it is proposed, fitted, scored, named and told apart.

    A subclass sets the class attributes and implements :meth:`propose` (which fits and
    scores with :func:`~balancer_id.diagnostics.arena.score`) and :meth:`sentence`; it is
    listed once in :data:`balancer_id.diagnostics.explanations.KINDS`.

    Attributes
    ----------
    key : str
        Registry key (unique).
    kind : str
        The CONTRACT.md ``kind`` of its explanations (several sensor kinds share
        ``sensor``).
    verdict : Verdict
        The verdict it leads to.
    stage : Stage
        When it is fitted.
    mimics : str
        What else gives the same data (said when two are close).
    separating_trial : str
        The recording that tells it apart from what it mimics.
    stands_alone : bool
        When it is the verdict, the library effects that would only mimic it are not
        offered as suggestions.
    changes_parameter : bool
        It lets a balancer's parameter change (split, drift, trend, pair).
    measurement : bool
        It is the sensor's, not the balancer's (said with note ``diagnose.sensor``).
    tried : str
        How the verdict names it among what was tried (empty: not named).
    """

    key: ClassVar[str] = ""
    kind: ClassVar[str] = ""
    verdict: ClassVar[Verdict] = Verdict.EFFECT_MISSING
    stage: ClassVar[Stage] = Stage.FIRST
    mimics: ClassVar[str] = ""
    separating_trial: ClassVar[str] = "record more thrust levels in both directions"
    stands_alone: ClassVar[bool] = False
    changes_parameter: ClassVar[bool] = False
    measurement: ClassVar[bool] = False
    tried: ClassVar[str] = ""

    def propose(self, inp: Any) -> list[Explanation]:
        """Its explanations of the current fit, fitted and scored.

        Parameters
        ----------
        inp : ArenaInput
            The current fit, its trials and the arena's criterion.

        Returns
        -------
        list of Explanation
        """
        return []

    def verdict_of(self, e: Explanation) -> Verdict:
        """The verdict ``e`` leads to (:attr:`verdict` unless the kind says otherwise).

        Parameters
        ----------
        e : Explanation

        Returns
        -------
        Verdict
        """
        return self.verdict

    def valid(self, e: Explanation, tests_failed: bool, threshold: float, min_drop: float) -> bool:
        """Whether ``e`` has a benefit: BIC falls by ``threshold``, not at its null value,
        and it removes more than ``min_drop`` of the error above the noise floor.

        Parameters
        ----------
        e : Explanation
        tests_failed : bool
            Whether a test an adequate verdict must pass failed.
        threshold : float
            BIC fall needed.
        min_drop : float
            Share of the excess error it must remove.

        Returns
        -------
        bool
        """
        return not e.null and e.delta_bic > threshold and e.excess_drop > min_drop

    def parts(self, e: Explanation, by_label: dict[str, Explanation]) -> list[float]:
        """The BIC falls of the explanations ``e`` combines (a pair's effect and split),
        each of which it must beat by the threshold to stand; empty for a single one.

        Parameters
        ----------
        e : Explanation
        by_label : dict
            Every explanation by its label.

        Returns
        -------
        list of float
        """
        return []

    def absorbs(self, e: Explanation, other: Explanation) -> bool:
        """Whether ``other`` is the same fit as ``e`` read another way (a sensor's gain and
        the bias effect): ``other`` then leaves the standing ones while ``e`` stands, and
        ``e``'s sentence names it.

        Parameters
        ----------
        e, other : Explanation

        Returns
        -------
        bool
        """
        return False

    def twin(self, e: Explanation, other: Explanation) -> bool:
        """Whether ``other`` names the same thing ``e`` does by another cause, so that no
        recording of this kind can tell them apart (a late acceleration channel and the
        balancer's dead time): the verdict is then ambiguous between them, whatever
        their BIC gap, with the trial that separates them.

        Parameters
        ----------
        e, other : Explanation

        Returns
        -------
        bool
        """
        return False

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """The verdict's paragraph naming ``e`` (what it is, what it changes, what to run).

        Parameters
        ----------
        e : Explanation
        fit : FitResult
            The fit diagnosed (its command is the base of the advice).

        Returns
        -------
        str
        """
        return head(e)

    def make(
        self,
        label: str,
        delta_bic: float,
        rmse: float,
        *,
        effects: list[str] | None = None,
        parameters: list[str] | None = None,
        detail: dict[str, object] | None = None,
        null: bool = False,
    ) -> Explanation:
        """An explanation of this kind.

        Parameters
        ----------
        label : str
        delta_bic : float
        rmse : float
        effects, parameters : list of str, optional
        detail : dict, optional
        null : bool

        Returns
        -------
        Explanation
        """
        return Explanation(
            self.kind,
            label,
            delta_bic,
            rmse,
            list(effects or []),
            list(parameters or []),
            dict(detail or {}),
            null=null,
            key=self.key,
        )


def head(e: Explanation) -> str:
    """``<label> lowers BIC by N and removes P of the error above the noise floor``.

    Parameters
    ----------
    e : Explanation

    Returns
    -------
    str
    """
    return (
        f"{e.label} lowers BIC by {e.delta_bic:.0f} and removes {e.excess_drop:.0%} of the "
        "error above the noise floor"
    )


#: The kinds by key, filled once by :mod:`balancer_id.diagnostics.explanations` from its
#: list (kept here so that an explanation finds its kind without importing the list).
_BY_KEY: dict[str, ExplanationKind] = {}


def register(kinds: tuple[ExplanationKind, ...]) -> None:
    """Record the kinds by key (each key once).

    Parameters
    ----------
    kinds : tuple of ExplanationKind
        Every kind, as :data:`~balancer_id.diagnostics.explanations.KINDS` lists them.

    Raises
    ------
    RuntimeError
        When two kinds share a key.
    """
    by_key = {k.key: k for k in kinds}
    if len(by_key) != len(kinds):
        raise RuntimeError("two explanation kinds share a key")
    _BY_KEY.update(by_key)


def kind_of(key: str) -> ExplanationKind:
    """The kind registered under ``key`` (an unknown key: a plain missing effect).

    Parameters
    ----------
    key : str

    Returns
    -------
    ExplanationKind
    """
    return _BY_KEY.get(key) or _BY_KEY["effect"]
