"""Experiment protocols that span stages (the external test set of `flashbrdf evaluate --test-dir`)."""
