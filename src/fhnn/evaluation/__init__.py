"""Evaluation: high-accuracy rollouts and metrics."""
