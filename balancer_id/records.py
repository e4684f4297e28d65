"""Results read back: a result's JSON as a frozen object that renders as the result did.

A fit, a diagnosis, an improve or a comparison is computed from trials (arrays, models,
kernels) that its JSON does not carry; what reads back from the JSON (the result cache,
``--params``, a saved ``--save`` file) is a :class:`ResultRecord`: the JSON object, deeply
frozen, with the accessors the renderers and exit codes need. ``X.from_dict(x.to_dict())``
gives a record whose :meth:`ResultRecord.to_dict` equals ``x.to_dict()``, so a result read
back renders (terminal, JSON) exactly as the result it was made from.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

from balancer_id.notes import Note

__all__ = [
    "ComparisonRecord",
    "DiagnosisRecord",
    "FitRecord",
    "FrozenDict",
    "ImproveRecord",
    "ReadsBack",
    "ResultRecord",
    "freeze",
    "thaw",
]

R = TypeVar("R", bound="ResultRecord")


class FrozenDict(dict[Any, Any]):
    """A read-only dict: it reads, iterates, compares, pickles and dumps to JSON as one
    (at a dict's speed), and refuses every change in place (a complete result's tables).

    Parameters
    ----------
    data : mapping or iterable of pairs
        The entries (copied).
    """

    def _refuse(self, *args: Any, **kwargs: Any) -> Any:
        """Refused: a FrozenDict is read-only (copy it with ``dict(...)`` to change it).

        Parameters
        ----------
        *args, **kwargs
            What ``dict``'s method of the same name takes.

        Raises
        ------
        TypeError
            Always.
        """
        raise TypeError("a FrozenDict is read-only: copy it with dict(...) to change it")

    __setitem__ = __delitem__ = __ior__ = _refuse
    clear = pop = popitem = setdefault = update = _refuse  # type: ignore[assignment]

    def __reduce__(self) -> tuple[Any, ...]:
        return (FrozenDict, (dict(self),))


def freeze(value: Any) -> Any:
    """A JSON value made immutable: mappings read-only, lists tuples, recursively.

    Parameters
    ----------
    value : object
        A JSON value (dicts, lists, scalars).

    Returns
    -------
    object
        A :class:`FrozenDict` for a mapping, a tuple for a list, the scalar as is.
    """
    if isinstance(value, Mapping):
        return FrozenDict({k: freeze(v) for k, v in value.items()})
    if isinstance(value, list | tuple):
        return tuple(freeze(v) for v in value)
    return value


def thaw(value: Any) -> Any:
    """The plain JSON value of a :func:`freeze` d one (a new dict or list each call).

    Parameters
    ----------
    value : object

    Returns
    -------
    object
    """
    if isinstance(value, Mapping):
        return {k: thaw(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return [thaw(v) for v in value]
    return value


@dataclass(frozen=True)
class ResultRecord:
    """A result's CONTRACT.md JSON object, read back and frozen.

    Attributes
    ----------
    data : Mapping
        The JSON object, frozen (:func:`freeze`): nothing in it can be set.
    """

    data: Mapping[str, Any]
    #: The :mod:`balancer_id.report.terminal` function that draws the object.
    printer: ClassVar[str] = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "data", freeze(self.data))

    @classmethod
    def from_dict(cls: type[R], data: Mapping[str, Any]) -> R:
        """The record of a JSON object (a result's ``to_dict()``, a cached or saved one).

        Parameters
        ----------
        data : mapping
            The JSON object.

        Returns
        -------
        ResultRecord
            Its :meth:`to_dict` equals ``data``.
        """
        return cls(data)

    def to_dict(self) -> dict[str, Any]:
        """The JSON object: a new, plain dict equal to the one read back."""
        return thaw(self.data)  # type: ignore[no-any-return]

    def __getitem__(self, key: str) -> Any:
        return self.data[key]

    def get(self, key: str, default: Any = None) -> Any:
        """The JSON's ``key``, or ``default``.

        Parameters
        ----------
        key : str
            A key of the JSON object.
        default : object
            What a missing key gives.

        Returns
        -------
        object
        """
        return self.data.get(key, default)

    @property
    def notes(self) -> list[Note]:
        """The typed notes of the JSON's ``notes`` (empty without them)."""
        return [Note.from_dict(thaw(n)) for n in self.data.get("notes") or ()]

    @property
    def trusted(self) -> bool:
        """False when the JSON says ``trusted: false`` (its own, or any group's)."""
        groups = self.data.get("groups")
        parts = groups if isinstance(groups, tuple) else (self.data,)
        return not any(isinstance(p, Mapping) and p.get("trusted") is False for p in parts)


class ReadsBack:
    """A result whose JSON reads back: ``X.from_dict(x.to_dict())`` is a frozen
    :attr:`record` of it (the JSON carries no trials to compute the result again)."""

    #: What the JSON reads back as.
    record: ClassVar[type[ResultRecord]] = ResultRecord

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ResultRecord:
        """The result read back from its JSON (a cached, saved or sent ``to_dict()``).

        Parameters
        ----------
        data : mapping
            A ``to_dict()`` object (JSON-ready).

        Returns
        -------
        ResultRecord
            A :attr:`record`: frozen, its ``to_dict()`` equal to ``data``, rendered as
            the result it came from.
        """
        return cls.record.from_dict(data)


@dataclass(frozen=True)
class FitRecord(ResultRecord):
    """A ``fit`` read back (:meth:`balancer_id.identify.result.FitResult.from_dict`)."""

    printer: ClassVar[str] = "print_fit"

    @property
    def model(self) -> str:
        """The model's spec."""
        return str(self.data["model"])

    @property
    def values(self) -> dict[str, float]:
        """Fitted (and held) parameter values by name."""
        return {k: p["value"] for k, p in self.data["parameters"].items()}

    @property
    def metrics(self) -> dict[str, float]:
        """CONTRACT.md error figures."""
        return dict(self.data["metrics"])


@dataclass(frozen=True)
class DiagnosisRecord(ResultRecord):
    """A ``diagnose`` read back
    (:meth:`balancer_id.diagnostics.diagnosis.Diagnosis.from_dict`)."""

    printer: ClassVar[str] = "print_diagnosis"

    @property
    def verdict(self) -> str:
        """The verdict."""
        return str(self.data["verdict"])


@dataclass(frozen=True)
class ImproveRecord(ResultRecord):
    """An ``improve`` read back
    (:meth:`balancer_id.diagnostics.improve.ImproveResult.from_dict`)."""

    printer: ClassVar[str] = "print_improve"

    @property
    def final_model(self) -> str:
        """Spec of the last accepted model."""
        return str(self.data["final_model"])


@dataclass(frozen=True)
class ComparisonRecord(ResultRecord):
    """A ``compare`` read back (:meth:`balancer_id.workflows.compare_logs.CompareRun.from_dict`)."""

    printer: ClassVar[str] = "print_compare"

    @property
    def models(self) -> list[str]:
        """The models compared, in order."""
        return [str(m["model"]) for m in self.data["models"]]
