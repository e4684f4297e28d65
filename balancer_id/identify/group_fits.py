"""Groups of trials identified each alone (``fit --group-by``): a FitResult per group."""

from __future__ import annotations

import html
from collections.abc import Iterator
from dataclasses import dataclass

from balancer_id.identify.result import FitResult


@dataclass(frozen=True)
class GroupFits:
    """One fit per group of trials (a payload changed between runs, several balancers).

    Attributes
    ----------
    group_by : str
        How the trials were grouped (``run``, ``log`` or ``runs:1-3,4-6``).
    groups : tuple of (str, FitResult)
        Each group's label and its fit, in the order of the runs.
    """

    group_by: str
    groups: tuple[tuple[str, FitResult], ...]

    def __iter__(self) -> Iterator[tuple[str, FitResult]]:
        return iter(self.groups)

    def __len__(self) -> int:
        return len(self.groups)

    def __getitem__(self, label: str) -> FitResult:
        """The fit of the group labelled ``label``."""
        for name, result in self.groups:
            if name == label:
                return result
        raise KeyError(f"no group {label!r}; the groups: {[n for n, _ in self.groups]}")

    @property
    def trusted(self) -> bool:
        """Every group's fit is trusted."""
        return all(result.trusted for _, result in self.groups)

    def to_dict(self) -> dict[str, object]:
        """The CONTRACT.md ``fit --group-by --json`` object: ``group_by`` and ``groups``.

        Returns
        -------
        dict
        """
        return {
            "group_by": self.group_by,
            "groups": [{"group": label, **result.to_dict()} for label, result in self.groups],
        }

    def lines(self) -> list[str]:
        """One line per group: its label, the parameters with standard errors, trusted."""
        out = [f"{len(self.groups)} group(s) by {self.group_by}:"]
        for label, result in self.groups:
            values = ", ".join(
                f"{p.name} = {p.value:.4g}" + (f" ± {p.stderr:.2g}" if p.stderr else "")
                for p in result.match.parameters.values()
            )
            flag = "" if result.trusted else "  NOT TRUSTED"
            out.append(f"  {label}: {values}{flag}")
        return out

    def __repr__(self) -> str:
        return "\n".join(self.lines())

    def _repr_html_(self) -> str:
        return "<pre>" + html.escape("\n".join(self.lines())) + "</pre>"
