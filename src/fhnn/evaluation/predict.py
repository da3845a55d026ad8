"""Forecasts from a given state, and the state a model sees in a track of observed positions.

- :func:`estimate_states`: the state ``(x, y, vx, vy)`` at the last sample of each observed track
  (noisy positions at irregular times, known forces) that the model explains best — the least
  squares fit of the model's own trajectory (RK4 with :data:`SUBSTEPS` steps per sample interval)
  to the positions, over the start state, by Gauss–Newton with Levenberg–Marquardt damping. A
  smoother's estimate at a track's end sees one side only; the fit uses every sample and the
  dynamics, so a forecast starts from a state the model can continue.
- :func:`forecast`: the model's rollout (adaptive Dopri8 landing on each output time, as
  evaluation rollouts) from start states at their own start times, with forces given at the
  output times (linearly interpolated between them), on a regular output grid.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.data.table import PAD_STEP, Table, Trajectory
from fhnn.errors import ConfigError
from fhnn.executables import StoredProgram
from fhnn.models.base import ROLLOUT_TOL, AbstractVectorField
from fhnn.physics.actuation import forcing, held_grid, no_actuation
from fhnn.physics.integrators import rk4_solve

Array = jax.Array

#: RK4 steps per sample interval when fitting a track (its error is then far below the noise).
SUBSTEPS = 4
#: Gauss–Newton iterations of the fit (it converges in a few on smooth tracks).
ITERATIONS = 12


def _refine(t: np.ndarray) -> np.ndarray:
    """The times ``t`` ``(N, K)`` with :data:`SUBSTEPS` − 1 equally spaced times inserted in each
    interval, shape ``(N, (K − 1)·SUBSTEPS + 1)``."""
    frac = np.arange(SUBSTEPS) / SUBSTEPS
    inner = t[:, :-1, None] + np.diff(t, axis=1)[..., None] * frac
    return np.concatenate([inner.reshape(t.shape[0], -1), t[:, -1:]], axis=1)


@eqx.filter_jit
def _fit(
    model: AbstractVectorField,
    guess: Array,
    t: Array,
    fine: Array,
    pos: Array,
    mask: Array,
    force: Array,
    last: Array,
) -> tuple[Array, Array, Array]:
    """Per track: the start state minimising the masked squared position residuals, and the
    model's state at the track's last real sample ``last``; also the RMS residual [m] and the
    covariance ``(4, 4)`` of that state: the fit's ``σ² (JᵀJ)⁻¹`` (σ² the residuals' variance
    with 4 degrees of freedom taken by the fit) carried to the last sample by the Jacobian of the
    model's trajectory."""

    def one(
        s0: Array, tt: Array, ff: Array, p: Array, m: Array, fk: Array, k: Array
    ) -> tuple[Array, Array, Array]:
        f = lambda s, time: model(s, time, forcing(jnp.zeros((2, 3, 3)), time, tt, fk))  # noqa: E731
        # one scale for both coordinates, over the real samples only: the noise is isotropic, so x
        # and y residuals weigh alike (only conditioning depends on it, not the minimiser)
        n = jnp.sum(m)
        centre = jnp.sum(p * m[:, None], axis=0) / n
        scale = jnp.maximum(jnp.sqrt(jnp.sum((p - centre) ** 2 * m[:, None]) / (2 * n)), 1e-3)

        def evaluate(s: Array) -> tuple[Array, Array, Array]:
            """The model's states at the samples ``(K, 4)``, their Jacobian in the start state
            ``(K, 4, 4)`` and the scaled residuals ``(2K,)``: one pass of RK4 carrying the four
            tangents beside the states."""

            def states(s: Array) -> tuple[Array, Array]:
                y = rk4_solve(f, s, ff)[::SUBSTEPS]
                return y, y

            jac, y = jax.jacfwd(states, has_aux=True)(s)
            return y, jac, (((y[:, :2] - p) / scale) * m[:, None]).ravel()

        def residual_jacobian(jac: Array) -> Array:
            return (jac[:, :2, :] / scale * m[:, None, None]).reshape(-1, 4)

        def step(carry: tuple[Array, ...], _: None) -> tuple[tuple[Array, ...], None]:
            # evaluate the trial state; keep it if it lowers the cost (the first trial, the
            # guess, always); then propose the next trial from the kept state's linearisation
            s, y, jac, r, cost, damp, trial = carry
            new = (trial, *evaluate(trial))
            new_cost = jnp.sum(new[3] ** 2)
            better = new_cost < cost
            s, y, jac, r = (jnp.where(better, a, b) for a, b in zip(new, (s, y, jac, r), strict=True))
            damp = jnp.where(jnp.isinf(cost), damp, jnp.where(better, damp * 0.3, damp * 10.0))
            cost = jnp.where(better, new_cost, cost)
            jr = residual_jacobian(jac)
            jtj, jtr = jr.T @ jr, jr.T @ r
            delta = jnp.linalg.solve(jtj + damp * jnp.diag(jnp.diag(jtj) + 1e-12), -jtr)
            return (s, y, jac, r, cost, damp, s + delta), None

        k_samples = p.shape[0]
        start = (
            s0,
            jnp.zeros((k_samples, 4)),
            jnp.zeros((k_samples, 4, 4)),
            jnp.zeros(2 * k_samples),
            jnp.asarray(jnp.inf),
            jnp.asarray(1e-3),
            s0,
        )
        # ITERATIONS Gauss–Newton steps, each evaluated once, after the guess's own evaluation
        (_, states, jac, r, _, _, _), _ = jax.lax.scan(step, start, None, length=ITERATIONS + 1)
        res = (states[:, :2] - p) * m[:, None]
        rms = jnp.sqrt(jnp.sum(res**2) / (2 * jnp.sum(m)))
        jr = residual_jacobian(jac)
        variance = jnp.sum(r**2) / jnp.maximum(2 * n - 4, 1)
        cov_start = variance * jnp.linalg.pinv(jr.T @ jr)
        carry = jac[k]
        return states[k], rms, carry @ cov_start @ carry.T

    return jax.vmap(one)(guess, t, fine, pos, mask, force, last)


#: The fit, kept compiled on disk (:mod:`fhnn.executables`): a later process fits histories of
#: the same padded shape (:func:`_bucket`) untraced.
_FIT = StoredProgram(_fit)


def _bucket(n: int) -> int:
    """The least size of the ladder 1, 2, 3, 4, 6, 8, 12, 16, 24, … (``2^j`` and ``3·2^j``) that
    holds ``n``: histories are padded to it, tracks and samples alike, so that histories of other
    lengths share a compiled fit (one per rung) at no more than twice the work."""
    return min(size for j in range(n.bit_length() + 1) for size in (2**j, 3 * 2**j) if size >= n)


def _padded_rows(n: int) -> np.ndarray:
    """Indices ``0 … n − 1`` then ``n − 1`` repeated, :func:`_bucket` ``(n)`` of them: a batch of
    ``n`` padded to its rung by repeating its last row (the first ``n`` results are its own)."""
    return np.minimum(np.arange(_bucket(n)), n - 1)


def estimate_states(
    model: AbstractVectorField,
    t: np.ndarray,
    pos: np.ndarray,
    *,
    mask: np.ndarray | None = None,
    force: np.ndarray | None = None,
    guess_velocity: np.ndarray | None = None,
    covariance: bool = False,
) -> tuple[np.ndarray, ...]:
    """The model's state at the last real sample of each observed track.

    Args:
        model: a trained vector field.
        t: sample times [s], shape ``(N, K)``, increasing along each row (padding after a shorter
            track's last sample must keep increasing; ``mask`` marks it).
        pos: observed positions [m], shape ``(N, K, 2)``.
        mask: ``(N, K)``, true at real samples (default: all); each track needs at least 3.
        force: known external forces [N] at the samples, ``(N, K, 2)`` (default: none).
        guess_velocity: a first guess of each track's velocity at its first sample [m/s],
            ``(N, 2)`` (default: the finite difference of its first two samples).
        covariance: also return each state's covariance.

    Returns:
        ``(states, rms)``: states ``(N, 4)`` [m, m, m/s, m/s] at each track's last real sample and
        the RMS position residual [m] of each fit (about the noise when the model explains the
        track); with ``covariance`` also ``cov`` ``(N, 4, 4)``, the states' covariance from the
        fit (the residuals' spread through the linearised fit, carried to the last sample).
    """
    t = np.asarray(t, dtype=float)
    pos = np.asarray(pos, dtype=float)
    if t.ndim != 2 or pos.shape != (*t.shape, 2):
        raise ConfigError(f"t must be (N, K) and pos (N, K, 2), got {t.shape} and {pos.shape}")
    mask = np.ones(t.shape, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    counts = mask.sum(axis=1)
    if np.any(counts < 3):
        raise ConfigError(
            f"a track needs at least 3 observed positions, track {int(np.argmin(counts))} has "
            f"{int(counts.min())}"
        )
    if np.any(np.diff(t, axis=1) <= 0):
        raise ConfigError("the sample times of each track must increase")
    force = np.zeros((*t.shape, 2)) if force is None else np.asarray(force, dtype=float)
    if guess_velocity is None:
        guess_velocity = (pos[:, 1] - pos[:, 0]) / (t[:, 1:2] - t[:, :1])
    guess = np.concatenate([pos[:, 0], guess_velocity], axis=1)
    pos = np.where(mask[..., None], pos, 0.0)
    # padded to the ladder's sizes: samples past the last (masked out, times still increasing),
    # tracks repeating the last (dropped from the result)
    n, size = t.shape
    extra = _bucket(size) - size
    t = np.concatenate([t, t[:, -1:] + PAD_STEP * np.arange(1, extra + 1)], axis=1)
    pos = np.concatenate([pos, np.zeros((n, extra, 2))], axis=1)
    mask = np.concatenate([mask, np.zeros((n, extra), dtype=bool)], axis=1)
    force = np.concatenate([force, np.repeat(force[:, -1:], extra, axis=1)], axis=1)
    rows = _padded_rows(n)
    states, rms, cov = _FIT(
        model,
        jnp.asarray(guess[rows]),
        jnp.asarray(t[rows]),
        jnp.asarray(_refine(t[rows])),
        jnp.asarray(pos[rows]),
        jnp.asarray(mask[rows], dtype=float),
        jnp.asarray(force[rows]),
        jnp.asarray(counts[rows] - 1),
    )
    states, rms, cov = (np.asarray(a)[:n] for a in (states, rms, cov))
    if covariance:
        return states, rms, cov
    return states, rms


def forecast(
    model: AbstractVectorField,
    start: np.ndarray,
    t: np.ndarray,
    force: np.ndarray | None = None,
    *,
    rtol: float = ROLLOUT_TOL,
    atol: float = ROLLOUT_TOL,
) -> tuple[np.ndarray, np.ndarray]:
    """Roll ``model`` out from ``start`` ``(N, 4)`` at ``t[:, 0]`` through the output times ``t``
    ``(N, T)`` [s], with known forces ``force`` ``(N, T, 2)`` [N] at those times (linear between
    them; default none). Returns ``(states (N, T, 4), ok (N,))``; a rollout that blows up
    (beyond :data:`~fhnn.models.base.BLOW_UP` times its start's scale) or runs out of steps is
    not ok. The batch is padded to a size of :func:`_bucket`'s ladder (its last rollout
    repeated, then dropped), so forecasts of other numbers of tracks share a compiled rollout."""
    start = np.asarray(start, dtype=float)
    t = np.asarray(t, dtype=float)
    force = np.zeros((*t.shape, 2)) if force is None else np.asarray(force, dtype=float)
    n = start.shape[0]
    rows = _padded_rows(n)
    states, ok = model.solve(start[rows], t[rows], no_actuation(rows.size), force[rows], rtol, atol)
    states, ok = np.asarray(states)[:n], np.asarray(ok)[:n]
    return states, ok & np.all(np.isfinite(states), axis=(1, 2))


#: Default span of a history fitted by :func:`predict_tracks` [s]: chosen on the validation
#: split of ``benchmarks/own_data.py`` (0.5, 1, 2, 3 s and the whole track tried; 1 s gave the
#: smallest 1 s and 5 s forecast errors).
FIT_WINDOW = 1.0


#: Start states drawn per fitted track from the fit's uncertainty (:func:`estimate_states`'s
#: covariance), each forecast too, for the band of :meth:`Forecast.of_ensemble`.
SAMPLES = 32


@dataclasses.dataclass(frozen=True)
class Forecast:
    """Forecasts of named tracks: ``t`` ``(N, T)`` [s], ``states`` ``(N, T, 4)``, ``ok`` ``(N,)``,
    the fitted history's RMS position residual ``fit_rms`` ``(N,)`` [m] (NaN without a history),
    and ``samples`` ``(S, N, T, 4)``: forecasts from start states drawn from the fit's
    uncertainty (NaN where one diverged; ``None`` without a history). For a band
    (:meth:`of_ensemble`) ``states`` is the members' median and ``band`` the states at the
    interval's two percentiles, ``(2, N, T, 4)``."""

    ids: list[str]
    t: np.ndarray
    states: np.ndarray
    ok: np.ndarray
    fit_rms: np.ndarray
    band: np.ndarray | None = None
    samples: np.ndarray | None = None

    @classmethod
    def of_ensemble(cls, members: list[Forecast], percentiles: tuple[float, float]) -> Forecast:
        """The members' median forecast with the ``percentiles`` band over every member's
        forecast and its start-state samples (so one model with samples gets a band too, from
        the uncertainty of its start); a track is ok where every member's is (a diverged member
        makes the band meaningless)."""
        states = np.stack([m.states for m in members])
        pool = np.concatenate([states, *(m.samples for m in members if m.samples is not None)])
        return cls(
            ids=members[0].ids,
            t=members[0].t,
            states=np.median(states, axis=0),
            ok=np.all([m.ok for m in members], axis=0),
            fit_rms=np.median([m.fit_rms for m in members], axis=0),
            band=np.nanpercentile(pool, percentiles, axis=0),
        )

    def columns(self) -> dict[str, np.ndarray]:
        """The forecasts as table columns ``traj_id, t, x, y, vx, vy`` (one row per output time),
        followed by ``x_lo, x_hi, y_lo, …`` for an ensemble's band."""
        size = self.t.shape[1]
        out = {
            "traj_id": np.repeat(np.asarray(self.ids, dtype=object), size).astype(str),
            "t": self.t.ravel(),
        }
        names = ("x", "y", "vx", "vy")
        for j, name in enumerate(names):
            out[name] = self.states[..., j].ravel()
        if self.band is not None:
            for j, name in enumerate(names):
                out[f"{name}_lo"], out[f"{name}_hi"] = (
                    self.band[0, ..., j].ravel(),
                    self.band[1, ..., j].ravel(),
                )
        return out


def _forces_at(
    forcing_table: dict[str | None, tuple[np.ndarray, np.ndarray]] | None,
    traj: str,
    t: np.ndarray,
    *,
    required: bool,
) -> np.ndarray | None:
    """Forces ``(len(t), 2)`` of track ``traj`` at times ``t`` from a forcing table (its own rows,
    or the table's common rows), linear between rows; ``None`` if the table has none for it or
    does not cover ``t`` and ``required`` is false."""
    if forcing_table is None:
        return None
    rows = forcing_table.get(traj, forcing_table.get(None))
    if rows is None:
        if required:
            raise ConfigError(f"the forcing table has no rows for trajectory {traj!r}")
        return None
    tf, force = rows
    if t[0] < tf[0] - 1e-9 or t[-1] > tf[-1] + 1e-9:
        if required:
            raise ConfigError(
                f"the forcing table covers t = {tf[0]:g}–{tf[-1]:g} s; the forecast of trajectory {traj!r} "
                f"needs {t[0]:g}–{t[-1]:g} s"
            )
        return None
    return np.stack([np.interp(t, tf, force[:, 0]), np.interp(t, tf, force[:, 1])], axis=1)


#: Most output times of one forecast track (a forecast's states are held in memory: 32 bytes per
#: time, track and drawn start state).
MAX_FORECAST_SAMPLES = 1_000_000


def _check_forecast(duration: float, dt: float, fit_window: float, samples: int) -> None:
    """Refuse a forecast's bad duration, step, fit window or sample count (a ConfigError)."""
    if not (np.isfinite(duration) and duration > 0):
        raise ConfigError(f"--duration must be > 0 s, got {duration!r}")
    if not (np.isfinite(dt) and 0 < dt <= duration):
        raise ConfigError(f"--dt must be > 0 s and at most the duration, got {dt!r}")
    if duration / dt > MAX_FORECAST_SAMPLES:
        raise ConfigError(
            f"--duration {duration:g} s at --dt {dt:g} s is {duration / dt:.3g} output samples per "
            f"track; at most {MAX_FORECAST_SAMPLES:,} (a longer --dt or a shorter --duration)"
        )
    if not (np.isfinite(fit_window) and fit_window > 0):
        raise ConfigError(f"--fit-window must be > 0 s, got {fit_window!r}")
    if samples < 0:
        raise ConfigError(f"--samples must be >= 0, got {samples}")


def _given_start(initial: np.ndarray, t0: float) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Track ids, start states ``(1, 4)``, start times ``(1,)`` [s] and fit RMS (NaN) of a
    forecast from one given state."""
    initial = np.asarray(initial, dtype=float)
    if initial.shape != (4,) or not np.all(np.isfinite(initial)):
        raise ConfigError(f"the initial state is x, y, vx, vy: four finite numbers, got {initial.tolist()}")
    if not np.isfinite(t0):
        raise ConfigError(f"--t0 must be finite, got {t0!r}")
    return ["initial"], initial[None], np.array([float(t0)]), np.array([np.nan])


def _fitted_starts(
    model: AbstractVectorField,
    history: Table,
    forcing_table: dict[str | None, tuple[np.ndarray, np.ndarray]] | None,
    fit_window: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each track's state at its last sample, fitted to its last ``fit_window`` seconds
    (:func:`estimate_states`): states ``(n, 4)``, fit RMS ``(n,)`` [m], covariances ``(n, 4, 4)``."""
    recent = []
    for tr in history.trajectories:
        keep = tr.t >= tr.t[-1] - fit_window - 1e-9
        if keep.sum() < 3:
            keep[-3:] = True
        recent.append(keep)
    size = max(int(k.sum()) for k in recent)
    n = len(recent)
    t = np.zeros((n, size))
    pos = np.zeros((n, size, 2))
    force = np.zeros((n, size, 2))
    mask = np.zeros((n, size), dtype=bool)
    guess = np.zeros((n, 2))
    for i, (tr, keep) in enumerate(zip(history.trajectories, recent, strict=True)):
        k = int(keep.sum())
        tt = tr.t[keep]
        t[i, :k], t[i, k:] = tt, tt[-1] + PAD_STEP * np.arange(1, size - k + 1)
        pos[i, :k], mask[i, :k] = tr.pos[keep], True
        f = (
            tr.force[keep]
            if tr.force is not None
            else _forces_at(forcing_table, tr.traj_id, tt, required=False)
        )
        if f is not None:
            force[i, :k] = f
        guess[i] = tr.vel[keep][0] if tr.vel is not None else (pos[i, 1] - pos[i, 0]) / (tt[1] - tt[0])
    return estimate_states(model, t, pos, mask=mask, force=force, guess_velocity=guess, covariance=True)


def _draw_starts(starts: np.ndarray, cov: np.ndarray, samples: int, seed: int) -> np.ndarray:
    """``samples`` start states per track ``(samples * n, 4)`` (sample-major), drawn from the
    normal distribution of each fitted state ``starts (n, 4)`` and covariance ``cov (n, 4, 4)``."""
    rng = np.random.default_rng(seed)
    sym = 0.5 * (cov + cov.swapaxes(1, 2))
    drawn = np.stack(
        [rng.multivariate_normal(starts[i], sym[i], samples, method="eigh") for i in range(len(starts))],
        axis=1,
    )
    return drawn.reshape(-1, 4)


def _with_forcing_rows(
    times: np.ndarray, ids: list[str], forcing_table: dict[str | None, tuple[np.ndarray, np.ndarray]] | None
) -> tuple[np.ndarray, np.ndarray]:
    """The output times ``times`` ``(N, T)`` with each track's forcing rows inside them added (the
    solver steps onto every time, so a force that changes at a row — a held step — changes there,
    not smeared over an output step), padded to one length by midpoints of the widest intervals:
    ``(grid (N, L), picks (N, T))``, ``grid[i, picks[i]] == times[i]``."""
    grids = []
    for i, traj in enumerate(ids):
        t = times[i]
        rows = None if forcing_table is None else forcing_table.get(traj, forcing_table.get(None))
        extra = np.zeros(0) if rows is None else rows[0][(rows[0] > t[0]) & (rows[0] < t[-1])]
        grids.append(np.union1d(t, extra))
    size = max(g.size for g in grids)
    for i, g in enumerate(grids):
        while g.size < size:
            j = int(np.argmax(np.diff(g)))
            g = np.insert(g, j + 1, 0.5 * (g[j] + g[j + 1]))
        grids[i] = g
    grid = np.stack(grids)
    picks = np.stack([np.searchsorted(grid[i], times[i]) for i in range(len(ids))])
    return grid, picks


def predict_tracks(
    model: AbstractVectorField,
    *,
    duration: float,
    dt: float,
    initial: np.ndarray | None = None,
    t0: float = 0.0,
    history: Table | None = None,
    forcing_table: dict[str | None, tuple[np.ndarray, np.ndarray]] | None = None,
    fit_window: float = FIT_WINDOW,
    samples: int = SAMPLES,
    seed: int = 0,
) -> Forecast:
    """Forecast ``duration`` [s] on a grid of about ``dt`` [s], either from one given ``initial``
    state ``(4,)`` at ``t0`` [s] (track id ``"initial"``), or from the end of each track of an
    observed ``history`` (a :class:`~fhnn.data.table.Table`), its state there estimated by
    :func:`estimate_states` from its last ``fit_window`` seconds (its observed velocities, if
    any, are the first guess; its ``Fx, Fy``, else the forcing table where it covers them, are the
    forces during the fit). Forces during the forecast come from ``forcing_table``
    (:func:`~fhnn.data.table.read_forcing`), which must then cover it; without one there are none.
    From a history, ``samples`` further start states per track are drawn (seeded by ``seed``) from
    the normal distribution of the fit's covariance and forecast too (``Forecast.samples``)."""
    _check_forecast(duration, dt, fit_window, samples)
    if (initial is None) == (history is None):
        raise ConfigError("give either an initial state or a history to start from, not both")
    cov: np.ndarray | None = None
    if initial is not None:
        ids, starts, start_t, fit_rms = _given_start(initial, t0)
    else:
        assert history is not None
        ids = [tr.traj_id for tr in history.trajectories]
        starts, fit_rms, cov = _fitted_starts(model, history, forcing_table, fit_window)
        start_t = np.array([tr.t[-1] for tr in history.trajectories])
    steps = max(1, round(duration / dt))
    times = start_t[:, None] + np.linspace(0.0, duration, steps + 1)[None, :]
    grid, picks = _with_forcing_rows(times, ids, forcing_table)
    forces = np.zeros((*grid.shape, 2))
    for i, traj in enumerate(ids):
        f = _forces_at(forcing_table, traj, grid[i], required=True)
        if f is not None:
            forces[i] = f
    n = len(ids)
    draws = 0
    if cov is not None and samples > 0:
        starts = np.concatenate([starts, _draw_starts(starts, cov, samples, seed)])
        draws = samples
    # the tracks' forecasts and those of their drawn start states, as one rollout
    rep = lambda a: np.broadcast_to(a, (1 + draws, *a.shape)).reshape(-1, *a.shape[1:])  # noqa: E731
    out, fine = forecast(model, starts, rep(grid), rep(forces))
    out = np.take_along_axis(out, rep(picks)[..., None], axis=1)  # the output times alone
    states, ok = out[:n], fine[:n]
    drawn = None
    if draws:
        drawn = np.where(fine[n:, None, None], out[n:], np.nan).reshape(draws, n, *out.shape[1:])
    return Forecast(ids=ids, t=times, states=states, ok=ok, fit_rms=fit_rms, samples=drawn)


@dataclasses.dataclass(frozen=True)
class BandCheck:
    """How often a forecast band held held-out observations (:func:`check_band`).

    Attributes:
        level: the band's nominal coverage (0.9 for a 5th–95th percentile band).
        coverage: the share of (position, axis) pairs whose observation lay inside the band,
            widened in quadrature by the observation noise, over ``horizon`` s after each track's
            first ``history`` s.
        scale: the factor on the band's half-widths (about the median) at which the share
            reaches ``level`` (1 where it already does: a band is never narrowed).
        tracks, points: the tracks and observed positions checked.
        history, horizon: seconds fitted, seconds forecast [s].
    """

    level: float
    coverage: float
    scale: float
    tracks: int
    points: int
    history: float
    horizon: float

    def to_dict(self) -> dict[str, float]:
        return dataclasses.asdict(self)

    def text(self) -> str:
        """One line: what the check found and what was done."""
        found = (
            f"on {self.tracks} validation track{'' if self.tracks == 1 else 's'} the {self.level:.0%} band "
            f"held {self.coverage:.0%} of "
            f"the observed positions over {self.horizon:g} s after a {self.history:g} s history"
        )
        if self.scale > 1.0:
            return f"{found}; widened ×{self.scale:.2g} to hold {self.level:.0%}"
        return found


def band_tracks(split: Any, ids: list[str], history: float, horizon: float) -> tuple[Table, dict, list]:
    """The tracks of ``split`` (ids ``ids``) long enough for a check: the first ``history`` s of
    each as a :class:`~fhnn.data.table.Table`, its forces over the whole track as a forcing table
    (held forcing as knots whose interpolant is the step, :func:`~fhnn.physics.actuation.held_grid`),
    and each track's observed ``(t, positions)`` after the history up to ``horizon`` s."""
    trajectories, forcing_rows, later = [], {}, []
    for i, traj in enumerate(ids):
        m = split.mask[i]
        t = np.broadcast_to(split.times, split.mask.shape)[i][m]
        pos, force = split.states[i][m][:, :2], split.forces[i][m]
        if t[-1] - t[0] < history + horizon:
            continue
        early = t <= t[0] + history
        if split.switch is None:
            trajectories.append(Trajectory(traj, t[early], pos[early], None, force[early]))
            forcing_rows[traj] = (t, force)
        else:  # held forcing: knots whose interpolant is the step, for the fit and the forecast
            grid, values, _ = held_grid(t[None], force[None], split.switch[i][m][None])
            trajectories.append(Trajectory(traj, t[early], pos[early], None, None))
            forcing_rows[traj] = (grid[0], values[0])
        after = (t > t[0] + history) & (t <= t[0] + history + horizon)
        later.append((t[after], pos[after]))
    table = Table(trajectories, sum(tr.t.size for tr in trajectories), 0)
    return table, forcing_rows, later


def band_scale(band: Forecast, later: list, noise: float, level: float) -> tuple[float, float, int]:
    """``(coverage, scale, points)`` of ``band`` (a :meth:`Forecast.of_ensemble`) against the
    observations ``later`` (``(t, positions)`` per track, as :func:`band_tracks` gives them) with
    position noise of std ``noise`` [m] (see :class:`BandCheck`)."""
    from scipy.stats import norm

    z = norm.ppf(0.5 + level / 2)
    needed = []
    for i, (t, pos) in enumerate(later):
        for axis in range(2):
            mid = np.interp(t, band.t[i], band.states[i, :, axis])
            lo = np.interp(t, band.t[i], band.band[0, i, :, axis])
            hi = np.interp(t, band.t[i], band.band[1, i, :, axis])
            d = pos[:, axis] - mid
            half = np.maximum(np.where(d >= 0, hi - mid, mid - lo), 1e-300)
            # |d| ≤ sqrt((k·half)² + (zσ)²) ⇔ k ≥ sqrt(max(d² − (zσ)², 0)) / half
            needed.append(np.sqrt(np.maximum(d**2 - (z * noise) ** 2, 0.0)) / half)
    k = np.concatenate(needed) if needed else np.zeros(0)
    if k.size == 0:
        raise ConfigError("no validation track is long enough to check the band")
    k = np.where(np.isfinite(k), k, np.inf)
    return float(np.mean(k <= 1.0)), float(max(1.0, np.quantile(k, level))), int(k.size // 2)


def widened(band: Forecast, scale: float) -> Forecast:
    """``band`` with its half-widths about the median multiplied by ``scale``."""
    if band.band is None or scale == 1.0:
        return band
    mid = band.states[None]
    return dataclasses.replace(band, band=mid + scale * (band.band - mid))
