"""Experiments: the paper's tables and figures, and reports."""
