"""Discovery of the missing term: the model's discrepancy as a sparse sum of candidate forces.

When no explanation of the arena (library effects, a parameter changed or drifting, the
sensor's low-pass) brings the residual to the noise floor, the missing force is searched as
a sparse combination of candidate terms in the states (SINDy for model discrepancy,
Kaheman et al. 2019), in the model's own units (N), and the whole model is refitted with
the chosen terms as one effect, so that the other parameters move with it.

How
---
1. The candidate terms (:func:`default_terms`: ``z``, ``v``, ``v*abs(v)``, ``v**3``,
   Coulomb ``sign(v)``, Stribeck ``sign(v)*exp(-abs(v)/v_s)`` over a grid of ``v_s``,
   ``sin``/``cos(2*pi*z/p)`` with ``p`` from the residual's spectrum over position,
   ``h*v``, ``z*v``, a constant; users add theirs) become one *library* effect whose force
   is ``sum q_j * term_j``, written as a user effect file in the cache folder and loaded
   through the same path as ``--effects-file`` (its kernel is compiled once and cached).
2. The fitted model plus the library at ``q = 0`` is simulated once with the output's
   sensitivities to every free parameter and every ``q_j``: the discrepancy force is then
   a linear regression (the Gauss-Newton step of the full output-error problem), in which
   the model's own parameters move freely and the terms compete. Rows are prewhitened with
   the resting noise's AR(2) coefficients (the arena's likelihood of coloured noise).
3. The sparse regression is scikit-learn's orthogonal matching pursuit path; the support
   with the lowest BIC wins, and a term stays only when removing it costs more than
   :data:`TERM_BIC` and it lowers the error on held-out trials (K-fold over trials).
   Bootstrap resamples of the trials give each kept term's inclusion probability (the
   share in which removing it from the model linearized at the refit still costs more
   than :data:`TERM_BIC`).
4. The whole model is refitted (nonlinear, simulation matching) with the chosen terms free
   and the others held at 0, scored by the arena's criterion (:func:`arena.score`): the
   discovery stands only when it beats the arena's best explanation on the same BIC.

The discovered effect is written by :func:`effect_source` in the README's plug-in form.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from balancer_id.diagnostics.discovery.files import check_effects_out, write_effect
from balancer_id.diagnostics.discovery.linear import _Linear, held_out_gain, select, term_price
from balancer_id.diagnostics.discovery.result import DiscoveredTerm, Discovery
from balancer_id.diagnostics.discovery.search import position_period, search
from balancer_id.diagnostics.discovery.settings import (
    BOOTSTRAP,
    CHALLENGE_BIC,
    CLOSE,
    CLOSE_BIC,
    COULOMB,
    LEFT_OVER,
    MARKER,
    MAX_TERMS,
    PERIOD_SAMPLES,
    PERIODIC,
    REFITTED,
    STRIBECK,
    STRIBECK_GRID,
    TERM_BIC,
)
from balancer_id.diagnostics.discovery.terms import (
    Term,
    default_terms,
    effect_name,
    friction_hook,
    library_effect,
    library_source,
)
from balancer_id.diagnostics.explanations.effect import LibraryEffect
from balancer_id.model.registry import Registry

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput, Explanation
    from balancer_id.diagnostics.context import DiagnosisContext

__all__ = [
    "BOOTSTRAP",
    "CHALLENGE_BIC",
    "CLOSE",
    "CLOSE_BIC",
    "COULOMB",
    "LEFT_OVER",
    "MARKER",
    "MAX_TERMS",
    "PERIODIC",
    "PERIOD_SAMPLES",
    "REFITTED",
    "STRIBECK",
    "STRIBECK_GRID",
    "TERM_BIC",
    "DiscoveredTerm",
    "Discovery",
    "Term",
    "_Linear",
    "challenges",
    "check_effects_out",
    "default_terms",
    "discover",
    "effect_name",
    "friction_hook",
    "held_out_gain",
    "library_effect",
    "library_source",
    "position_period",
    "select",
    "should_try",
    "term_price",
    "write_effect",
]

def should_try(best: Explanation | None, noise_floor: float, tests_failed: bool) -> bool:
    """Whether to search for a term: a test failed and the arena's best leaves error.

    Parameters
    ----------
    best : Explanation or None
        The arena's best standing explanation.
    noise_floor : float
        Acceleration noise (m/s^2).
    tests_failed : bool
        Whether one of the adequacy tests failed for the current fit.

    Returns
    -------
    bool
        True when the best explanation changes a parameter (a missing force depending
        on the speed or the thrust looks like one), or when a test failed and there is
        no standing explanation or the best one leaves an error above the noise floor
        larger than :data:`LEFT_OVER` x the noise.
    """
    if best is not None and best.explainer.changes_parameter:
        return True
    if not tests_failed:
        return False
    if best is None:
        return True
    left = math.sqrt(max(best.rmse**2 - noise_floor**2, 0.0))
    return noise_floor <= 0 or left > LEFT_OVER * noise_floor


def challenges(best: Explanation | None, registry: Registry) -> bool:
    """Whether the arena's best is a library dry-friction law that the discovery's
    friction terms generalize, so that the search challenges it even at the noise floor.

    A constant friction level (Karnopp's) is the special case of Coulomb with Stribeck at
    ``F_s = 0``; where the friction falls with the speed, it reaches the noise floor with
    the viscosity bent to absorb the rest. The discovery must then beat it by
    :data:`CHALLENGE_BIC` (the ``margin`` of :func:`discover`).

    Parameters
    ----------
    best : Explanation or None
        The arena's best standing explanation.
    registry : Registry
        Where its effects are found.

    Returns
    -------
    bool
    """
    if best is None or best.key != LibraryEffect.key:
        return False
    return any(name in registry and "friction" in registry[name].hooks() for name in best.effects)


def discover(
    inp: ArenaInput,
    ctx: DiagnosisContext,
    *,
    rival: Explanation | None = None,
    command: str = "",
    terms: Sequence[Term] | None = None,
    extra_terms: Sequence[Term] = (),
    seed: int = 0,
    margin: float = 0.0,
) -> Discovery | None:
    """Search the missing force, refit the whole model with it, and score it.

    Parameters
    ----------
    inp : ArenaInput
        The current fit, its trials, the noise's AR(2) coefficients.
    ctx : DiagnosisContext
        The fit's trials with their simulated states.
    rival : Explanation, optional
        The arena's best explanation: the discovery must beat its BIC fall.
    command : str
        The command that writes the discovered effect (for the record).
    terms : sequence of Term, optional
        The candidate library; None: :func:`default_terms`.
    extra_terms : sequence of Term
        The user's own terms, added to the library.
    seed : int
        Seed of the bootstrap.
    margin : float
        BIC by which the discovery must beat ``rival`` (0: any fall beyond it).

    Returns
    -------
    Discovery or None
        None when no term pays in BIC and on held-out trials, or when the refit does not
        beat ``rival`` by ``margin``.
    """
    # the refits wander through bad regions (overflow, 0/0) before they settle: the
    # optimizer handles those steps, so their floating-point warnings are not news
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        return search(inp, ctx, rival, command, terms, extra_terms, seed, margin)
