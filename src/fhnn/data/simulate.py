"""Batched ground-truth simulation of a scenario into a :class:`~fhnn.data.dataset.Dataset`.

Trajectories are integrated many at once (``jax.vmap`` over an adaptive Dopri8 solve, compiled
once per data set: every split runs through the same padded batch shape) at
``rtol = atol = 1e-12`` by default, with steps landing on every sample time (an error of 1.6e-12
over 20 s of ``steady_vortex`` against scipy DOP853 at 1e-13).
Trajectories a scenario rejects (the obstacle's close approaches) or on which the solver fails are
redrawn from the same random stream, and the number of redraws is recorded in the data set (``redraws``).

Random streams: one :class:`numpy.random.SeedSequence` per data set, spawned into independent
streams for the scenario's frozen random parts, each split's initial states and forcing, and the
observation noise. The same seed gives bit-identical arrays.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable
from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.config import Config, check_nonnegative, check_positive, frozen_config
from fhnn.data.conversion import forcing_at_samples
from fhnn.data.dataset import SPLITS, Dataset, Split
from fhnn.errors import ConfigError, SimulationError
from fhnn.executables import StoredProgram
from fhnn.physics.actuation import actuation_force, held_grid, no_actuation, sample_actuation
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.integrators import solve_forced_batch
from fhnn.physics.scenarios import DatasetDefaults, Scenario
from fhnn.runtime import __version__

#: The batched solve, kept compiled on disk (:mod:`fhnn.executables`): a later process simulates
#: a scenario of the same structure and shapes untraced.
_SOLVE = StoredProgram(solve_forced_batch)

#: Step budget of a simulated trajectory's solve. Steps land on every sample time, so a trajectory
#: of more samples than this cannot be simulated (:meth:`SimulationConfig.validate` says so).
MAX_STEPS = 200_000
#: Bytes of memory per sample of a data set while it is simulated: states, clean states,
#: derivatives and forces (14 float64 values), held twice while the batches are joined.
BYTES_PER_SAMPLE = 2 * 14 * 8
#: Bytes per sample of one batch's solve (its states, kept by the solver and copied out).
BYTES_PER_BATCH_SAMPLE = 3 * 4 * 8


def physical_memory() -> int | None:
    """This machine's memory in bytes, or ``None`` where the system does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


#: ``progress(split, done, total)`` is called after every batch.
ProgressFn = Callable[[str, int, int], None]


@frozen_config
class SimulationConfig(Config):
    """Settings of a simulated data set (defaults: the scenario's, see :meth:`for_scenario`).

    Attributes:
        n_traj: trajectories over all splits (at least one per split).
        duration: length of train and val trajectories [s].
        test_duration: length of test trajectories [s].
        dt: sampling interval [s].
        split: fractions (train, val, test); val and test get at least one trajectory each.
        seed: seed of every random draw.
        actuation: "random" (docs/spec.md §1 sinusoidal forcing) or "none".
        actuation_amplitude: upper bound of the forcing amplitudes [N].
        actuation_f_min, actuation_f_max: range of the forcing frequencies [Hz].
        obs_noise: standard deviation of Gaussian noise added to the stored observed states.
        rtol, atol: tolerances of the adaptive integrator.
        batch_size: trajectories integrated at once.
        max_redraw_rounds: give up after this many rounds of redrawing rejected trajectories.
    """

    config_name = "simulation"

    n_traj: int = DatasetDefaults.n_traj
    duration: float = DatasetDefaults.duration
    test_duration: float = DatasetDefaults.test_duration
    dt: float = DatasetDefaults.dt
    split: tuple[float, float, float] = DatasetDefaults.split
    seed: int = 0
    actuation: Literal["none", "random"] = DatasetDefaults.actuation
    actuation_amplitude: float = 1.0
    actuation_f_min: float = 0.05
    actuation_f_max: float = 0.5
    obs_noise: float = DatasetDefaults.obs_noise
    rtol: float = 1e-12
    atol: float = 1e-12
    batch_size: int = 256
    max_redraw_rounds: int = 50

    def validate(self) -> None:
        check_positive(self, "dt", "duration", "test_duration", "rtol", "atol", "batch_size")
        check_nonnegative(
            self, "actuation_amplitude", "actuation_f_min", "actuation_f_max", "obs_noise", "seed"
        )
        if self.n_traj < 1:
            raise ConfigError(f"simulation: n_traj must be >= 1, got {self.n_traj}")
        if any(f < 0 for f in self.split) or not math.isclose(sum(self.split), 1.0, abs_tol=1e-9):
            raise ConfigError(f"simulation: split fractions must be >= 0 and sum to 1, got {self.split}")
        for name in ("duration", "test_duration"):
            if getattr(self, name) < self.dt:
                raise ConfigError(
                    f"simulation: {name} ({getattr(self, name)} s) is shorter than dt ({self.dt} s)"
                )
        if self.actuation_f_min > self.actuation_f_max:
            raise ConfigError("simulation: actuation_f_min must not exceed actuation_f_max")
        counts = self.split_sizes()
        if min(counts.values()) < 1:
            raise ConfigError(
                f"simulation: n_traj = {self.n_traj} is too small for split {self.split}: "
                f"{counts} (every split needs at least one trajectory; use n_traj >= 3)"
            )
        samples = {name: self.sample_count(name) for name in counts}
        longest = max(samples.values())
        if longest - 1 > MAX_STEPS:
            raise ConfigError(
                f"simulation: {longest:,} samples per trajectory (duration / dt) are more than the "
                f"solver's {MAX_STEPS:,} steps, and it steps onto every sample: a longer dt or a "
                f"shorter duration"
            )
        need = BYTES_PER_SAMPLE * sum(counts[k] * samples[k] for k in counts)
        need += BYTES_PER_BATCH_SAMPLE * min(self.batch_size, self.n_traj) * longest
        memory = physical_memory()
        if memory is not None and need > memory:
            raise ConfigError(
                f"simulation: {self.n_traj:,} trajectories of up to {longest:,} samples need about "
                f"{need / 2**30:.3g} GiB of memory, more than this machine's {memory / 2**30:.3g} GiB: "
                f"fewer trajectories, a shorter duration or a longer dt"
            )

    @classmethod
    def for_scenario(cls, scenario: Scenario, **overrides: object) -> SimulationConfig:
        """The scenario's data-set defaults with ``overrides`` (``None`` values are ignored)."""
        values: dict[str, object] = dataclasses.asdict(scenario.defaults)
        values.update({k: v for k, v in overrides.items() if v is not None})
        return cls.from_dict(values)

    def split_sizes(self) -> dict[str, int]:
        """Trajectories per split."""
        n_val = max(1, round(self.n_traj * self.split[1])) if self.split[1] > 0 else 0
        n_test = max(1, round(self.n_traj * self.split[2])) if self.split[2] > 0 else 0
        return {"train": self.n_traj - n_val - n_test, "val": n_val, "test": n_test}

    def sample_count(self, split: str) -> int:
        """Samples per trajectory of ``split``: ``0, dt, …`` up to the duration."""
        duration = self.test_duration if split == "test" else self.duration
        return math.floor(duration / self.dt + 1e-9) + 1

    def times(self, split: str) -> np.ndarray:
        """Sample times of ``split`` [s], shape ``(T,)``: ``0, dt, …`` up to the duration."""
        return self.dt * np.arange(self.sample_count(split), dtype=np.float64)


@eqx.filter_jit
def derivatives_and_forces(
    eom: EquationsOfMotion, states: jax.Array, ts: jax.Array, act: jax.Array
) -> tuple[jax.Array, jax.Array]:
    """``(ds/dt, F_ext)`` at ``states`` ``(N, T, 4)`` and times ``ts`` ``(T,)`` under forcing ``act``."""

    def one(s: jax.Array, t: jax.Array, a: jax.Array) -> tuple[jax.Array, jax.Array]:
        force = actuation_force(a, t)
        return eom(s, t, force), force

    over_time = jax.vmap(one, in_axes=(0, 0, None))
    return jax.vmap(over_time, in_axes=(0, None, 0))(states, ts, act)


def integrate(
    eom: EquationsOfMotion,
    initial_states: np.ndarray,
    actuation: np.ndarray,
    ts: np.ndarray,
    *,
    rtol: float = 1e-12,
    atol: float = 1e-12,
    batch_size: int = 256,
    progress: Callable[[int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate many trajectories of ``eom``.

    Args:
        eom: equations of motion.
        initial_states: shape ``(N, 4)``.
        actuation: forcing parameters, shape ``(N, 2, 3, 3)``.
        ts: output times [s], shape ``(T,)``, starting at the initial time.
        rtol, atol: integrator tolerances.
        batch_size: trajectories per compiled batch; every batch is padded to this size, so one
            compilation serves all calls with the same ``batch_size`` and ``T``.
        progress: called with the number of trajectories done after each batch.

    Returns:
        ``(states, ok)`` of shapes ``(N, T, 4)`` and ``(N,)``.
    """
    n = initial_states.shape[0]
    size = batch_size
    ts_j = jnp.asarray(ts)
    states, oks = [], []
    for start in range(0, n, size):
        stop = min(start + size, n)
        idx = np.minimum(np.arange(start, start + size), n - 1)  # pad with the last trajectory
        # steps land on every sample time (no interpolation): 1.6e-12 real error at tol 1e-12
        ys, ok = _SOLVE(
            eom, jnp.asarray(initial_states[idx]), jnp.asarray(actuation[idx]), ts_j, rtol, atol, MAX_STEPS
        )
        states.append(np.asarray(ys)[: stop - start])
        oks.append(np.asarray(ok)[: stop - start])
        if progress is not None:
            progress(stop)
    return np.concatenate(states), np.concatenate(oks)


def integrate_held(
    eom: EquationsOfMotion,
    initial_states: np.ndarray,
    ts: np.ndarray,
    rows: list[tuple[np.ndarray, np.ndarray]],
    *,
    rtol: float = 1e-12,
    atol: float = 1e-12,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Integrate trajectories of ``eom`` under held (step-wise) known forces, stepping onto every
    change: the truth for thrusters that switch between samples.

    Args:
        eom: equations of motion.
        initial_states: shape ``(N, 4)``.
        ts: output times [s], shape ``(T,)``, starting at the initial time; at most one change
            of a trajectory's force between two of them.
        rows: per trajectory, the times [s] ``(K,)`` (the first at or before ``ts[0]``) and
            forces [N] ``(K, 2)`` of its forcing rows, each held until the next.
        rtol, atol: integrator tolerances.

    Returns:
        ``(states (N, T, 4), forces (N, T, 2), switch (N, T), ok (N,))``: the states, the force
        in effect at each output time and its change time in each interval
        (:func:`~fhnn.data.conversion.forcing_at_samples`).
    """
    n = initial_states.shape[0]
    forces, switch = np.empty((n, ts.size, 2)), np.empty((n, ts.size))
    for i, track in enumerate(rows):
        forces[i], switch[i] = forcing_at_samples(ts, track, "previous", str(i))
    grid, values, picks = held_grid(np.broadcast_to(ts, (n, ts.size)), forces, switch)
    ys, ok = solve_forced_batch(
        eom,
        jnp.asarray(initial_states),
        jnp.asarray(no_actuation(n)),
        jnp.asarray(grid),
        rtol,
        atol,
        MAX_STEPS,
        None,
        jnp.asarray(values),
    )
    states = np.take_along_axis(np.asarray(ys), picks[..., None], axis=1)
    return states, forces, switch, np.asarray(ok)


def simulate_dataset(
    scenario: Scenario, config: SimulationConfig, *, progress: ProgressFn | None = None
) -> Dataset:
    """Simulate the train, val and test splits of ``scenario`` under ``config``.

    Splits with the same sample times are integrated together, and every group through one
    compiled program: its times are padded to the longest group's by repeating the last time (the
    solver steps onto each time, so the states up to the group's own end are those of an unpadded
    solve, bit for bit), and all groups use the batch size of the smallest.

    Raises:
        SimulationError: when rejected or failed trajectories still remain after
            ``config.max_redraw_rounds`` rounds of redrawing.
    """
    streams = np.random.SeedSequence(config.seed).spawn(2 + len(SPLITS))
    scenario = scenario.resolve(np.random.default_rng(streams[0]))
    body = scenario.body()
    eom = EquationsOfMotion.of(scenario.flow(), body)
    noise_rng = np.random.default_rng(streams[1])
    rngs = {name: np.random.default_rng(s) for name, s in zip(SPLITS, streams[2:], strict=True)}
    sizes = config.split_sizes()
    groups: dict[int, list[str]] = {}
    for name in SPLITS:
        groups.setdefault(config.times(name).size, []).append(name)
    clean: dict[str, np.ndarray] = {}
    act: dict[str, np.ndarray] = {}
    redraws: dict[str, int] = {}
    longest = max(groups)
    batch = min(config.batch_size, *(sum(sizes[n] for n in names) for names in groups.values()))
    for names in groups.values():
        ts = config.times(names[0])
        padded = np.concatenate([ts, np.full(longest - ts.size, ts[-1])])
        label = "+".join(names)
        total = sum(sizes[n] for n in names)
        report = (lambda done, label=label, total=total: progress(label, done, total)) if progress else None
        owner = np.concatenate([np.full(sizes[n], i) for i, n in enumerate(names)])
        draws = [_draw(scenario, config, rngs[n], sizes[n]) for n in names]
        y0 = np.concatenate([d[0] for d in draws])
        forcing = np.concatenate([d[1] for d in draws])
        states, forcing, counts = _simulate_group(
            scenario, eom, config, [rngs[n] for n in names], owner, y0, forcing, padded, batch, label, report
        )
        for i, name in enumerate(names):
            clean[name], act[name], redraws[name] = (
                states[owner == i, : ts.size],
                forcing[owner == i],
                counts[i],
            )
    splits: dict[str, Split] = {}
    for name in SPLITS:
        ts = config.times(name)
        derivs, forces = derivatives_and_forces(
            eom, jnp.asarray(clean[name]), jnp.asarray(ts), jnp.asarray(act[name])
        )
        observed = clean[name].copy()  # never the same array as states_clean
        if config.obs_noise > 0:
            observed += noise_rng.normal(0.0, config.obs_noise, observed.shape)
        splits[name] = Split(
            t=ts,
            states=observed,
            states_clean=clean[name],
            derivs=np.asarray(derivs),
            forces=np.asarray(forces),
            actuation=act[name],
        )
    return Dataset(
        scenario=scenario.name,
        scenario_params=scenario.to_dict(),
        body_params=body.to_dict(),
        seed=config.seed,
        dt=config.dt,
        actuation=config.actuation,
        obs_noise=config.obs_noise,
        version=__version__,
        splits=splits,
        extra={"simulation": config.to_dict(), "redraws": redraws},
    )


def _draw(
    scenario: Scenario, config: SimulationConfig, rng: np.random.Generator, n: int
) -> tuple[np.ndarray, np.ndarray]:
    y0 = scenario.sample_initial_states(rng, n)
    if config.actuation == "random":
        act = sample_actuation(
            rng,
            n,
            amplitude=config.actuation_amplitude,
            f_min=config.actuation_f_min,
            f_max=config.actuation_f_max,
        )
    else:
        act = no_actuation(n)
    return y0, act


def _simulate_group(
    scenario: Scenario,
    eom: EquationsOfMotion,
    config: SimulationConfig,
    rngs: list[np.random.Generator],
    owner: np.ndarray,
    y0: np.ndarray,
    act: np.ndarray,
    ts: np.ndarray,
    batch: int,
    label: str,
    progress: Callable[[int], None] | None,
) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Integrate ``batch`` trajectories at a time, then redraw rejected ones (each from its own
    split's stream)."""
    solve = lambda y, a, report=None: integrate(  # noqa: E731
        eom, y, a, ts, rtol=config.rtol, atol=config.atol, batch_size=batch, progress=report
    )
    states, ok = solve(y0, act, progress)
    counts = [0] * len(rngs)
    for _ in range(config.max_redraw_rounds):
        bad = ~ok | scenario.rejected(states)
        if not bad.any():
            return states, act, counts
        for i, rng in enumerate(rngs):
            idx = np.flatnonzero(bad & (owner == i))
            if idx.size:
                counts[i] += idx.size
                y0[idx], act[idx] = _draw(scenario, config, rng, idx.size)
        idx = np.flatnonzero(bad)
        states[idx], ok[idx] = solve(y0[idx], act[idx])
    bad = ~ok | scenario.rejected(states)
    raise SimulationError(
        f"{scenario.name}: {int(bad.sum())} of {y0.shape[0]} {label} trajectories still rejected or "
        f"failed after {config.max_redraw_rounds} rounds of redrawing ({sum(counts)} redraws)"
    )


def simulate(scenario: str | Scenario, *, progress: ProgressFn | None = None, **settings: object) -> Dataset:
    """A data set of ``scenario`` (a name or a :class:`Scenario`) with the scenario's default
    settings, any :class:`SimulationConfig` field overridden by ``settings``; e.g.
    ``simulate("steady_vortex", n_traj=30, duration=5.0, seed=1)``."""
    from fhnn.physics.scenarios import get_scenario

    sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
    return simulate_dataset(sc, SimulationConfig.for_scenario(sc, **settings), progress=progress)
