"""Identification: the paper's method and simulation matching over all trials."""

from balancer_id.identify.api import fit, fit_match, resolve_model, trial_data
from balancer_id.identify.classic import ClassicResult, paper_method
from balancer_id.identify.data import TrialData
from balancer_id.identify.matching import MatchResult, match_trials
from balancer_id.identify.result import FitResult

__all__ = [
    "ClassicResult",
    "FitResult",
    "MatchResult",
    "TrialData",
    "fit",
    "fit_match",
    "match_trials",
    "paper_method",
    "resolve_model",
    "trial_data",
]
