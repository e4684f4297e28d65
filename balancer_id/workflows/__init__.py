"""Workflows: the library calls that chain the layers below (a command is parse, call,
render).

- :func:`~balancer_id.workflows.full_report.full_report`: identify, diagnose, improve, write.
- :func:`~balancer_id.workflows.plan.plan`: the trials to record next (issue 34.3).
"""

from balancer_id.workflows.full_report import FullReport, full_report
from balancer_id.workflows.plan import Plan, plan

__all__ = ["FullReport", "Plan", "full_report", "plan"]
