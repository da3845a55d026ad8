"""Data sets of a body that turns: simulated trajectories of a
:class:`~fhnn.physics.planar_scenarios.PlanarScenario`, and their HDF5 files.

A :class:`PlanarDataset` holds three splits (train, val, test), each with every trajectory's
sample times ``t`` ``(N, T)`` [s], states ``(N, T, 6)`` = ``(x, y, ψ, u, v, r)`` as trained on and
as scored against, the known body-frame forces ``(N, T, 3)`` = ``(X, Y, N)`` [N, N, N·m] at the
samples and the thrusters' sinusoid parameters ``(N, 3, 3, 3)``. Between samples the force is the
sinusoids plus the linear interpolant of what they leave at the samples
(:func:`~fhnn.physics.planar.body_force`): exactly the thrusters for a simulation, exactly the
linear interpolant of the table for an import (whose sinusoids are zero). The body's mass, yaw
inertia and centre of gravity are known constants of the data set; a simulation's scenario
parameters (its truth) are kept beside them.

Trajectories of a split may differ in length (imports): ``lengths`` ``(N,)`` counts each one's
samples, and past them times go on in steps of :data:`~fhnn.data.table.PAD_STEP` with the last
state and force repeated.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path
from typing import Any

import equinox as eqx
import h5py
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.errors import DataFormatError, SimulationError
from fhnn.files import atomic_output, check_input_file
from fhnn.physics.actuation import actuation_force
from fhnn.physics.integrators import adaptive_solve
from fhnn.physics.planar import body_force
from fhnn.physics.planar_scenarios import PlanarScenario, get_planar_scenario

Array = jax.Array

SPLITS = ("train", "val", "test")
#: The file's root attribute ``kind``, which tells a turning body's data set from a point body's.
KIND = "planar"
TRUTH_TOL = 1e-10


@dataclasses.dataclass(frozen=True)
class PlanarSplit:
    """One split of ``N`` trajectories padded to ``T`` samples.

    Attributes:
        t: sample times [s], ``(N, T)``, increasing along each row.
        states: the states trained on, ``(N, T, 6)``: a simulation's observed states (noise
            added, if any) or an import's smoothed estimates.
        states_clean: the states scored against, ``(N, T, 6)``: a simulation's noise-free truth,
            or an import's observed pose beside the estimated velocities.
        forces: known body-frame forces and moment at the samples, ``(N, T, 3)`` [N, N, N·m].
        thrust: the thrusters' sinusoids, ``(N, 3, 3, 3)`` (zero for an import).
        lengths: each trajectory's number of samples, ``(N,)``.
    """

    t: np.ndarray
    states: np.ndarray
    states_clean: np.ndarray
    forces: np.ndarray
    thrust: np.ndarray
    lengths: np.ndarray

    def residual(self) -> np.ndarray:
        """The forces less the sinusoids at the samples, ``(N, T, 3)``: what
        :func:`~fhnn.physics.planar.body_force` interpolates (zero to rounding for a simulation)."""
        return self.forces - np.asarray(_forces(jnp.asarray(self.thrust), jnp.asarray(self.t)))

    def valid(self) -> np.ndarray:
        """Which samples are the trajectories' own (not padding), ``(N, T)`` bools."""
        return np.arange(self.t.shape[1])[None, :] < self.lengths[:, None]


@dataclasses.dataclass(frozen=True)
class PlanarDataset:
    """A turning body's data set.

    Attributes:
        scenario: the scenario's name (``"imported"`` for a table); params: its parameters (the
            truth), or for an import only ``{"time_dependent": bool}``.
        seed: the data seed; obs_noise: the noise's standard deviation on every state entry
            [m, m, rad, m/s, m/s, rad/s] (for an import: the estimated noise of the positions [m]).
        mass, inertia, x_g: the body's known constants [kg, kg·m², m].
        splits: ``{"train", "val", "test"}`` → :class:`PlanarSplit`.
    """

    scenario: str
    params: dict[str, Any]
    seed: int
    obs_noise: float
    mass: float
    inertia: float
    x_g: float
    splits: dict[str, PlanarSplit]

    @property
    def has_truth(self) -> bool:
        """Whether the data were simulated (their truth known)."""
        return "added_mass" in self.params

    @property
    def time_dependent(self) -> bool:
        """Whether the flow may change with time (a simulation's modulation, an import's flag)."""
        return bool(self.params.get("time_dependent", self.params.get("gamma_modulation", 0.0)))

    def truth(self) -> PlanarScenario:
        """The scenario that made the data.

        Raises:
            DataFormatError: the data were imported (no truth).
        """
        if not self.has_truth:
            raise DataFormatError("an imported data set has no truth to compare with")
        return PlanarScenario.from_dict(self.params)


@eqx.filter_jit
def solve_planar(
    field: eqx.Module, y0: Array, thrust: Array, t: Array, residual: Array, *, tol: float, bound: float | None
) -> tuple[Array, Array]:
    """Trajectories of ``ṡ = field(s, t, τ(t))`` with Dopri8 stepping onto every sample time.

    Args:
        field: the true equations or a model, called as ``field(state (6,), t, τ (3,))``.
        y0: starts, ``(N, 6)``; thrust: sinusoids, ``(N, 3, 3, 3)``.
        t: output times [s], ``(N, T)``; residual: the forces less the sinusoids at them,
            ``(N, T, 3)`` (:func:`~fhnn.physics.planar.body_force`).
        tol: rtol = atol; bound: as :func:`~fhnn.physics.integrators.adaptive_solve`'s.

    Returns:
        ``(states (N, T, 6), ok (N,))``.
    """

    def one(s0: Array, a: Array, times: Array, r: Array) -> tuple[Array, Array]:
        return adaptive_solve(
            lambda s, tt: field(s, tt, body_force(a, tt, times, r)),
            s0,
            times,
            rtol=tol,
            atol=tol,
            dense=False,
            bound=bound,
        )

    return jax.vmap(one)(y0, thrust, t, residual)


@jax.jit
def _forces(thrust: Array, t: Array) -> Array:
    """The thrusters' forces ``(N, T, 3)`` at times ``t`` ``(N, T)`` for parameters ``(N, 3, 3, 3)``."""
    return jax.vmap(lambda a, ts: jax.vmap(lambda tt: actuation_force(a, tt))(ts))(thrust, t)


def simulate_planar(
    scenario: str | PlanarScenario = "turning_vortex",
    *,
    n_traj: int = 100,
    duration: float = 20.0,
    test_duration: float = 20.0,
    dt: float = 0.05,
    split: tuple[float, float, float] = (0.7, 0.2, 0.1),
    obs_noise: float = 0.0,
    seed: int = 0,
) -> PlanarDataset:
    """Simulate a turning body's train, val and test trajectories.

    Args:
        scenario: a name of :data:`~fhnn.physics.planar_scenarios.PLANAR_SCENARIOS` or a scenario.
        n_traj: trajectories over all splits; split: their fractions (train, val, test).
        duration: length of the train and val trajectories [s]; test_duration: of the test ones.
        dt: sampling interval [s].
        obs_noise: standard deviation of the noise added to every observed state entry.
        seed: the data seed (starts, thrusters, noise).

    Returns:
        The data set; the truth is integrated with Dopri8 at rtol = atol = 1e-10.

    Raises:
        ConfigError: an unknown scenario or a bad setting.
        SimulationError: a trajectory the solver could not finish.
    """
    from fhnn.errors import ConfigError

    sc = get_planar_scenario(scenario) if isinstance(scenario, str) else scenario
    name = scenario if isinstance(scenario, str) else "custom"
    if n_traj < 3 or not all(f > 0 for f in split) or not math.isclose(sum(split), 1.0):
        raise ConfigError(
            f"need n_traj >= 3 and three positive split fractions summing to 1, got {n_traj}, {split}"
        )
    if not (dt > 0 and duration >= dt and test_duration >= dt and obs_noise >= 0):
        raise ConfigError("dt, duration and test_duration must be positive (durations >= dt), obs_noise >= 0")
    sizes = [max(1, round(f * n_traj)) for f in split[:2]]
    sizes.append(n_traj - sum(sizes))
    if sizes[2] < 1:
        raise ConfigError(f"{n_traj} trajectories leave none for the test split")
    rng = np.random.default_rng(seed)
    eom = sc.equations()
    splits = {}
    for split_name, n in zip(SPLITS, sizes, strict=True):
        length = test_duration if split_name == "test" else duration
        ts = np.tile(np.arange(round(length / dt) + 1) * dt, (n, 1))
        y0, thrust = sc.sample_initial_states(rng, n), sc.sample_thrust(rng, n)
        states, ok = solve_planar(
            eom,
            jnp.asarray(y0),
            jnp.asarray(thrust),
            jnp.asarray(ts),
            jnp.zeros((*ts.shape, 3)),
            tol=TRUTH_TOL,
            bound=None,
        )
        if not bool(jnp.all(ok)):
            raise SimulationError(f"{int(jnp.sum(~ok))} {split_name} trajectories of {name} did not finish")
        forces = _forces(jnp.asarray(thrust), jnp.asarray(ts))
        clean = np.asarray(states)
        observed = clean + (rng.normal(0.0, obs_noise, clean.shape) if obs_noise > 0 else 0.0)
        lengths = np.full(n, ts.shape[1])
        splits[split_name] = PlanarSplit(ts, observed, clean, np.asarray(forces), thrust, lengths)
    return PlanarDataset(name, sc.to_dict(), seed, obs_noise, sc.mass, sc.inertia, sc.x_g, splits)


def write_planar(dataset: PlanarDataset, path: str | os.PathLike[str]) -> Path:
    """Write ``dataset`` to an HDF5 file at ``path`` (whole or not at all); returns the path."""
    with atomic_output(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["kind"] = KIND
        f.attrs["scenario"] = dataset.scenario
        f.attrs["params"] = json.dumps(dataset.params)
        for key in ("seed", "obs_noise", "mass", "inertia", "x_g"):
            f.attrs[key] = getattr(dataset, key)
        for name, split in dataset.splits.items():
            g = f.create_group(name)
            for field in dataclasses.fields(split):
                g.create_dataset(field.name, data=getattr(split, field.name))
    return Path(path)


def read_planar(path: str | os.PathLike[str]) -> PlanarDataset:
    """Read a file :func:`write_planar` wrote.

    Raises:
        DataFormatError: not such a file, or an array of the wrong shape.
    """
    path = check_input_file(path, "turning-body data set")
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("kind") != KIND:
                raise DataFormatError(f"{path} is not a turning body's data set (no kind = {KIND!r})")
            splits = {}
            for name in SPLITS:
                g = f[name]
                splits[name] = PlanarSplit(*(np.asarray(g[k.name]) for k in dataclasses.fields(PlanarSplit)))
            attrs = {k: f.attrs[k] for k in ("seed", "obs_noise", "mass", "inertia", "x_g")}
            out = PlanarDataset(
                str(f.attrs["scenario"]),
                json.loads(f.attrs["params"]),
                int(attrs["seed"]),
                float(attrs["obs_noise"]),
                float(attrs["mass"]),
                float(attrs["inertia"]),
                float(attrs["x_g"]),
                splits,
            )
    except (OSError, KeyError) as err:
        raise DataFormatError(f"{path}: not a readable turning-body data set ({err})") from None
    for name, s in out.splits.items():
        n, t = s.states.shape[:2]
        shapes = {
            "t": (n, t),
            "states": (n, t, 6),
            "states_clean": (n, t, 6),
            "forces": (n, t, 3),
            "thrust": (n, 3, 3, 3),
            "lengths": (n,),
        }
        for key, shape in shapes.items():
            if getattr(s, key).shape != shape:
                raise DataFormatError(f"{path}: {name}/{key} has shape {getattr(s, key).shape}, not {shape}")
    return out


__all__ = [
    "PlanarDataset",
    "PlanarSplit",
    "read_planar",
    "simulate_planar",
    "solve_planar",
    "write_planar",
]
