"""A discovery: its kept terms, the refit, and its effect file's source."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from balancer_id.diagnostics.discovery.settings import (
    MARKER,
)
from balancer_id.diagnostics.discovery.terms import Term, _class_name, _py, friction_hook
from balancer_id.identify.matching import MatchResult

if TYPE_CHECKING:
    from balancer_id.diagnostics.explanations.base import Explanation


# ---- the result -------------------------------------------------------------------------


@dataclass
class DiscoveredTerm:
    """One kept term of a discovery (CONTRACT.md ``discovery.terms``)."""

    term: Term
    coefficient: float
    stderr: float | None
    inclusion: float

    @property
    def expression(self) -> str:
        """The term as Python in ``f, v, z, h``, shape constants as numbers."""
        return self.term.concrete()

    def to_dict(self) -> dict[str, object]:
        """CONTRACT.md ``discovery.terms`` record."""
        return {
            "expression": self.expression,
            "coefficient": self.coefficient,
            "stderr": self.stderr,
            "unit": self.term.unit,
            "inclusion": self.inclusion,
        }


@dataclass
class Discovery:
    """A discovered force and the refit of the whole model with it.

    Attributes
    ----------
    terms : list of DiscoveredTerm
        The kept terms.
    delta_bic : float
        Fall of BIC against the current fit (the arena's criterion).
    rmse : float
        RMSE of the refit (m/s^2).
    rival : str or None
        The arena's best explanation it beat, and its BIC fall.
    command : str
        The command that writes it as an effect and refits.
    refit : MatchResult
        The whole model refitted with the terms (the library effect, other terms at 0).
    states : dict of str to numpy.ndarray
        ``f, v, z, h`` of the refit and ``residual_force``: the refit's force discrepancy
        plus the discovered force (what the terms were fitted to), over every sample.
    """

    terms: list[DiscoveredTerm]
    delta_bic: float
    rmse: float
    command: str
    refit: MatchResult = field(repr=False)
    rival: dict[str, object] | None = None
    excess_drop: float = 0.0
    #: What the refit held: the fit's own held values, the shapes, the other terms at 0.
    fixed: dict[str, float] = field(default_factory=dict, repr=False)
    #: Terms that fit about as well as a chosen one (within :data:`CLOSE_BIC`):
    #: ``{instead_of, expression, coefficient, bic_drop}``; the data cannot tell them apart.
    alternatives: list[dict[str, object]] = field(default_factory=list)
    states: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    #: Whether the friction terms act with a stick band (the model has no friction effect).
    stick: bool = False

    @property
    def formula(self) -> str:
        """``F = c1*(term1) + c2*(term2)`` (N)."""
        parts = []
        for t in self.terms:
            c = f"{t.coefficient:.4g}"
            e = t.expression
            simple = re.fullmatch(r"\w+", e)
            parts.append(c if e == "1.0" else f"{c}*{e}" if simple else f"{c}*({e})")
        return "F = " + (" + ".join(parts).replace("+ -", "- ") if parts else "0")

    def force(self, f: np.ndarray, v: np.ndarray, z: np.ndarray, h: np.ndarray) -> np.ndarray:
        """The discovered force at the given states (N).

        Parameters
        ----------
        f, v, z, h : numpy.ndarray
            States.

        Returns
        -------
        numpy.ndarray
        """
        out = np.zeros(np.shape(v), dtype=float)
        for t in self.terms:
            out = out + t.coefficient * t.term.evaluate(f, v, z, h)
        return out

    def main_state(self) -> str:
        """The state the first term depends on most (``z`` or ``v``, for the plot)."""
        e = self.terms[0].term.expression if self.terms else "z"
        return "z" if re.search(r"\bz\b", e) else "v" if re.search(r"\bv\b", e) else "h"

    def to_dict(self) -> dict[str, object]:
        """The CONTRACT.md ``discovery`` object."""
        return {
            "formula": self.formula,
            "terms": [t.to_dict() for t in self.terms],
            "bic_drop": self.delta_bic,
            "rmse_after": self.rmse,
            "excess_error_drop": self.excess_drop,
            "beats": self.rival,
            "alternatives": self.alternatives,
            "command": self.command,
        }

    def explanation(self) -> Explanation:
        """The discovery as one of the arena's explanations (kind ``discovered``)."""
        from balancer_id.diagnostics.explanations.base import kind_of

        e = kind_of("discovered").make(
            f"discovered force {self.formula}",
            self.delta_bic,
            self.rmse,
            detail={
                "formula": self.formula,
                "values": self.refit.values(),
                "alternatives": self.alternatives,
            },
        )
        e.excess_drop = self.excess_drop
        e.source = self
        return e

    def effect_source(self, name: str = "discovered", evidence: str = "") -> str:
        """The discovered force as a user effect file (the README's plug-in form).

        Parameters
        ----------
        name : str
            The effect's spec name (a Python identifier).
        evidence : str
            What the docstring says about the evidence (log, BIC, held-out error).

        Returns
        -------
        str
            Python source: one :class:`~balancer_id.model.effect.Effect` subclass whose
            ``force`` hook is the formula, its coefficients Params started at the
            discovered values, with units from the terms.
        """
        q = json.dumps
        params, args, body, doc = _term_parts(self.terms, self.stick)
        dry = [t for t in self.terms if self.stick and t.term.is_friction]
        sliding = " + ".join(_product(t.term.name, t.expression) for t in dry)
        formula = " + ".join(body) or "0.0"
        whole = " + ".join(x for x in (" + ".join(body), sliding) if x)
        hooks = (
            [
                "    @staticmethod",
                f"    def force(f, v, z, h, {', '.join(args)}):",
                f"        return {formula}",
            ]
            if body
            else []
        )
        if dry:
            hooks += [*([""] if hooks else []), *_dry_friction_hook(dry, args)]
            doc.append(
                "    The sign(v) terms are dry friction: a load at rest sticks while the other\n"
                "    forces stay below their level at v = 0 (the friction hook)."
            )
        rival = (
            f" (the best library explanation, {self.rival['label']}, by "
            f"{float(self.rival['delta_bic']):.0f})"  # type: ignore[arg-type]
            if self.rival
            else ""
        )
        lines = [
            MARKER,
            f'"""A force found by balancer-id (improve --discover): F = {whole} (N)."""',
            "",
            "import math  # noqa: F401  (the terms may use it)",
            "",
            "from balancer_id import Effect, Param",
            "",
            "",
            f"class {_class_name(name)}(Effect):",
            f'    """Discovered force ``F = {whole}`` (N).',
            "",
            f"    Fitted: {self.formula} (N).",
            *doc,
            f"    Evidence: BIC falls by {self.delta_bic:.0f} against the model without it"
            f"{rival}; RMSE {self.rmse:.4g} m/s^2.",
            *([f"    {evidence}"] if evidence else []),
            "    Edit the formula or the bounds freely: it is a user effect like any other.",
            '    """',
            "",
            f"    name = {q(name)}",
            f"    summary = {q('discovered force ' + self.formula)}",
            f"    source = {q('balancer-id improve --discover')}",
            "    parameters = (",
            *params,
            "    )",
            "",
            *hooks,
            "",
        ]
        return "\n".join(lines)


def _term_parts(
    terms: list[DiscoveredTerm], stick: bool
) -> tuple[list[str], list[str], list[str], list[str]]:
    """Per term: its ``Param`` line, its argument, its product in the force (not a dry
    friction term's when the load sticks) and its docstring lines."""
    q = json.dumps
    params, args, body, doc = [], [], [], []
    for t in terms:
        c, e = t.coefficient, t.expression
        span = float(f"{max(1e3 * abs(c), 1e-6):.3g}")
        se = f" +- {t.stderr:.2g}" if t.stderr is not None and np.isfinite(t.stderr) else ""
        fields = [q(t.term.name), _py(float(f"{c:.6g}")), _py(-span), _py(span)]
        fields += [q(t.term.unit), q("coefficient of " + e)]
        one = f"        Param({', '.join(fields)}),"
        params.append(
            one
            if len(one) <= 100
            else "        Param(\n"
            + "".join(f"            {x},\n" for x in fields)
            + "        ),"
        )
        args.append(t.term.name)
        if not (stick and t.term.is_friction):
            body.append(_product(t.term.name, e))
        doc.append(
            f"    {t.term.name} = {c:.4g}{se} {t.term.unit} (term {e}),\n"
            f"    kept in {t.inclusion:.0%} of the bootstrap resamples of the trials."
        )
    return params, args, body, doc


def _dry_friction_hook(dry: list[DiscoveredTerm], args: list[str]) -> list[str]:
    """The friction hook's lines for the dry (sign(v)) terms, their shapes filled in."""
    magnitudes = [t.term.magnitude for t in dry]
    for key, value in (kv for t in dry for kv in t.term.shapes):
        magnitudes = [re.sub(rf"\b{key}\b", f"{value:.4g}", m) for m in magnitudes]
    hook = friction_hook([t.term.name for t in dry], magnitudes, ", ".join(args))
    return hook.rstrip("\n").split("\n")


def _product(coef: str, expression: str) -> str:
    """``coef*expression``, with brackets only around a compound expression."""
    if expression == "1.0":
        return coef
    return f"{coef}*{expression}" if re.fullmatch(r"\w+", expression) else f"{coef}*({expression})"
