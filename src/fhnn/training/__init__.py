"""Training: losses, optimisers, checkpoints."""
