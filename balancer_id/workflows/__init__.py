"""Workflows: the library calls that chain the layers below (a command is parse, call,
render).

- :func:`~balancer_id.workflows.full_report.full_report`: identify, diagnose, improve, write.
- :func:`~balancer_id.workflows.plan.plan`: the trials to record next (issue 34.3).
- :class:`~balancer_id.workflows.fit_logs.FitJob`: ``fit``'s checks, ``--params``,
  ``--group-by``, the result cache and the files written.
- :func:`~balancer_id.workflows.compare_logs.compare_logs`,
  :func:`~balancer_id.workflows.simulate_log.simulate_log`, and
  :mod:`~balancer_id.workflows.examine` (``inspect``, ``diagnose``, ``improve``).
"""

from balancer_id.workflows.full_report import FullReport, full_report
from balancer_id.workflows.plan import Plan, plan

__all__ = ["FullReport", "Plan", "full_report", "plan"]
