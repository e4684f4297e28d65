"""A ``fit`` request, typed, and the result-cache key derived from all of it."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from balancer_id.trials import ReadOptions


@dataclass(frozen=True)
class FitRequest:
    """Everything a ``balancer-id fit`` result depends on.

    Attributes
    ----------
    logs : tuple of str
        The logs, in order.
    model : str or None
        The model spec (None: the default).
    fixed : dict of str to float
        ``--fix`` values.
    options : ReadOptions
        How the logs are read.
    per_trial : bool
        ``--per-trial``.
    starts : int or None
        ``--starts`` (None: the default search).
    trajectory : str or None
        ``--trajectory`` as given.
    effects_files : tuple of str
        ``--effects-file`` paths.
    track : tuple of str
        ``--track`` parameters.
    per_log : tuple of str
        ``--per-log`` parameters.
    """

    logs: tuple[str, ...]
    model: str | None = None
    fixed: dict[str, float] = field(default_factory=dict)
    options: ReadOptions = field(default_factory=ReadOptions)
    per_trial: bool = False
    starts: int | None = None
    trajectory: str | None = None
    effects_files: tuple[str, ...] = ()
    track: tuple[str, ...] = ()
    per_log: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """Every field, JSON-ready (no field can be left out: they are walked)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, ReadOptions):
                value = value.to_dict()
            elif isinstance(value, tuple):
                value = list(value)
            out[f.name] = value
        return out

    def cache_key(self) -> str | None:
        """The result-cache key: the request and the bytes of every file it reads.

        Returns
        -------
        str or None
            None when a file cannot be read (the result is then not cached).
        """
        from balancer_id import cache

        return cache.result_key("fit", [*self.logs, *self.effects_files, *self.trajectory_files()],
                                self.to_dict())

    def trajectory_files(self) -> list[str]:
        """The ``--trajectory`` CSV file, when the trajectory is one (its bytes are an input).

        Returns
        -------
        list of str
            ``[path]`` when ``trajectory`` names an existing file rather than a spec, else ``[]``.
        """
        text = self.trajectory
        if text is None or text.startswith("trapezoid") or not Path(text).exists():
            return []
        return [text]
