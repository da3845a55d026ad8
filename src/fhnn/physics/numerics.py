"""Small numerical helpers whose derivatives stay finite everywhere."""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array

_TINY = 1e-300


def safe_norm_squared(v: Array) -> Array:
    """``Σ v_i²`` over the last axis (plain; its gradient is finite everywhere)."""
    return jnp.sum(v * v, axis=-1)


def safe_norm(v: Array) -> Array:
    """``‖v‖`` over the last axis, with a zero (not NaN) gradient at ``v = 0``."""
    sq = safe_norm_squared(v)
    positive = sq > _TINY
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, sq, 1.0)), 0.0)
