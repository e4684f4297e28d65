"""Workflows: the library calls that chain the layers below (a command is parse, call,
render).

- :func:`~balancer_id.workflows.full_report.report`: identify, diagnose, improve, write.
"""

from balancer_id.workflows.full_report import FullReport, report

__all__ = ["FullReport", "report"]
