"""Segmentation: vertical motion, thrust steps and the step trials of a log."""

from balancer_id.segment.find import find_trials
from balancer_id.segment.gravity import VerticalMotion, vertical_motion
from balancer_id.segment.trial import Trial

__all__ = ["Trial", "VerticalMotion", "find_trials", "vertical_motion"]
