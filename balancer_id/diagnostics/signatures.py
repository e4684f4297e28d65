"""How each missing effect shows in the residual (MODEL.md, "Residual signatures").

A check looks at a :class:`~balancer_id.diagnostics.context.DiagnosisContext` and returns a
:class:`Signature`: a strength in [0, 1], the evidence in numbers and words, and start
values for the quick refit. Each effect carries its own check as a ``signature(ctx)``
classmethod in its module, built-in and user effects alike; an effect without one is
judged by the refit alone, with :func:`check_generic` (the residual's correlation with
the states) as evidence. :class:`Signature` is defined in
:mod:`balancer_id.model.signature` (the effects cannot import the diagnosis) and
importable from here.
"""

from __future__ import annotations

import warnings

import numpy as np

from balancer_id.diagnostics.context import DiagnosisContext
from balancer_id.diagnostics.residual_tests import state_correlations
from balancer_id.model.signature import Signature, clip01

__all__ = ["Signature", "check_generic", "signature_of"]


def check_generic(ctx: DiagnosisContext) -> Signature:
    """No specific signature: report where the residual lives (states it follows).

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    Signature
        Strength in [0, 1], the evidence in words and numbers (the state the
        residual follows best); no start values.
    """
    corr = state_correlations(ctx)
    if not corr:
        return Signature(0.0, "no motion to correlate with")
    name, r = max(corr.items(), key=lambda kv: abs(kv[1]))
    return Signature(
        clip01((abs(r) - 0.2) / 0.5),
        f"the residual follows the {name} (r = {r:+.2f})",
    )


def signature_of(effect: type, ctx: DiagnosisContext) -> Signature:
    """Run the effect's own check (its ``signature`` classmethod), or the generic one.

    Parameters
    ----------
    effect : type
        An :class:`~balancer_id.model.effect.Effect` subclass. Its ``signature(ctx)``
        classmethod is used when it has one; otherwise :func:`check_generic`.
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    Signature

    Raises
    ------
    TypeError
        When an effect's own ``signature`` returns something other than a Signature.
    """
    own = getattr(effect, "signature", None)
    check = own if callable(own) else check_generic
    # Short trials (<= 0.5 s after the step), a single direction or level leave some
    # statistics without data: numpy's warnings about them are expected, and such a check
    # simply finds nothing.
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        sig = check(ctx)
    if not isinstance(sig, Signature):
        raise TypeError(f"{getattr(effect, 'name', effect)}.signature must return a Signature")
    if not np.isfinite(sig.strength):
        return Signature(0.0, f"{sig.evidence} (too little data for this check)", sig.start)
    sig.start = {k: float(v) for k, v in sig.start.items() if np.isfinite(v)}
    return sig
