"""The discovery of a missing force, by stage (its entry: ``diagnostics.discover``)."""
