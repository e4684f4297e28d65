"""Workflows: the library calls that chain the layers below (a command is parse, call,
render).

- :func:`~balancer_id.workflows.full_report.full_report`: identify, diagnose, improve, write.
"""

from balancer_id.workflows.full_report import FullReport, full_report

__all__ = ["FullReport", "full_report"]
