"""The ``balancer-id`` command (see :mod:`balancer_id.cli.app`)."""

from balancer_id.cli.app import app, main
from balancer_id.text import printable as _printable

__all__ = ["_printable", "app", "main"]
