"""Rendering: terminal tables, JSON, plots, HTML and PDF reports."""
