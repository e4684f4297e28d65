"""Diagnosis: where the model fails, which effect is missing, and adding it."""

from balancer_id.diagnose.diagnosis import Diagnosis, Suggestion, diagnose_match

__all__ = ["Diagnosis", "Suggestion", "diagnose_match"]
