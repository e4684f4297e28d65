"""The ``balancer-id`` command (see :mod:`balancer_id.cli.app`)."""

from balancer_id.cli.app import app, main

__all__ = ["app", "main"]
