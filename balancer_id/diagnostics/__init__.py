"""Diagnosis: where the model fails, which effect is missing, and adding it."""

from balancer_id.diagnostics.api import compare, diagnose, fit_and_diagnose, improve
from balancer_id.diagnostics.compare import ModelComparison, compare_models
from balancer_id.diagnostics.diagnosis import Diagnosis, Suggestion, diagnose_match
from balancer_id.diagnostics.improve import ImproveResult, improve_model

__all__ = [
    "Diagnosis",
    "ImproveResult",
    "ModelComparison",
    "Suggestion",
    "compare",
    "compare_models",
    "diagnose",
    "diagnose_match",
    "fit_and_diagnose",
    "improve",
    "improve_model",
]
