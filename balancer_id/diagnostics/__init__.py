"""Diagnosis: where the model fails, which effect is missing, and adding it."""

from balancer_id.diagnostics.api import compare, diagnose, improve
from balancer_id.diagnostics.compare import ModelComparison, compare_models
from balancer_id.diagnostics.diagnosis import Diagnosis, ResidualTests, Suggestion
from balancer_id.diagnostics.improve import ImproveResult, ImproveStep

__all__ = [
    "Diagnosis",
    "ImproveResult",
    "ImproveStep",
    "ModelComparison",
    "ResidualTests",
    "Suggestion",
    "compare",
    "compare_models",
    "diagnose",
    "improve",
]
