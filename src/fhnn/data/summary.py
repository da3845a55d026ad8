"""What a data set covers: split sizes and the ranges of ``r``, speed and ``σ``.

The region the training data covers matters downstream: a rollout that leaves it measures
extrapolation, not interpolation (docs/spec.md §5).
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.data.dataset import SPLITS, Dataset, Split
from fhnn.physics.dynamics import EquationsOfMotion


@eqx.filter_jit
def _relative_speed(eom: EquationsOfMotion, states: jax.Array, ts: jax.Array) -> jax.Array:
    return jax.vmap(eom.relative_speed)(states, ts)


def relative_speeds(eom: EquationsOfMotion, states: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """``σ = ‖v − u(x, t)‖ + ε`` [m/s] in the flow of ``eom`` for states of shape ``(..., 4)`` at
    times ``ts`` broadcastable to ``states.shape[:-1]``; shape ``states.shape[:-1]``."""
    states = np.asarray(states)
    shape = states.shape[:-1]
    flat_t = np.broadcast_to(np.asarray(ts, dtype=float), shape).reshape(-1)
    out = _relative_speed(eom, jnp.asarray(states.reshape(-1, 4)), jnp.asarray(flat_t))
    return np.asarray(out).reshape(shape)


def coverage(dataset: Dataset, split: Split) -> dict[str, tuple[float, float]]:
    """Ranges ``(min, max)`` over the real samples of ``split``'s clean states of ``r`` [m] (from
    :attr:`~fhnn.data.dataset.Dataset.centre`),
    ``|v|`` [m/s], ``|F_ext|`` [N] and, where the data set knows its flow (simulated data),
    ``σ = ‖v − u‖ + ε`` [m/s]."""
    s = split.states_clean[split.mask]
    as_range = lambda a: (float(np.min(a)), float(np.max(a)))  # noqa: E731
    out = {
        "r": as_range(np.hypot(*(s[..., :2] - dataset.centre).T)),
        "speed": as_range(np.hypot(s[..., 2], s[..., 3])),
        "force": as_range(np.hypot(split.forces[split.mask][:, 0], split.forces[split.mask][:, 1])),
    }
    if not dataset.imported:
        out["sigma"] = as_range(relative_speeds(dataset.equations(), s, split.times[split.mask]))
    return out


def summarize(dataset: Dataset) -> dict[str, Any]:
    """A JSON-serialisable description of ``dataset``: metadata, split sizes and coverage."""
    splits = {}
    for name in SPLITS:
        split = dataset[name]
        splits[name] = {
            "n_traj": split.n_traj,
            "n_times": split.n_times,  # the longest trajectory's samples
            "samples": int(np.sum(split.sample_counts)),
            "duration": split.duration,
            "coverage": coverage(dataset, split),
        }
    return {
        "scenario": dataset.scenario,
        "scenario_params": dataset.scenario_params,
        "body_params": dataset.body_params,
        "seed": dataset.seed,
        "dt": dataset.dt,
        "actuation": dataset.actuation,
        "obs_noise": dataset.obs_noise,
        "version": dataset.version,
        "redraws": dataset.extra.get("redraws", {}),
        "measured": list(dataset.measured),
        "imported": dataset.extra.get("import", {}),
        "splits": splits,
    }
