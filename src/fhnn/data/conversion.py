"""A table's trajectories into a data set (``fhnn import``): splits, padding, estimated
derivatives and the import record."""

from __future__ import annotations

import dataclasses

import numpy as np

from fhnn.data.cleaning import GAP_STEPS, OUTLIER_SIGMAS, split_at_gaps, without_outliers
from fhnn.data.dataset import IMPORTED, SPLITS, Dataset, Split, within_intervals
from fhnn.data.derivatives import AUTO, choose_smoother, derivative_error, noise_level, smooth_derivatives
from fhnn.data.table import MIN_SAMPLES, PAD_STEP, Table, Trajectory, check_forcing_hold, position_series
from fhnn.errors import ConfigError, DataFormatError
from fhnn.runtime import __version__

#: How many dropped glitches the import record locates (the count is always whole).
OUTLIERS_LISTED = 20


@dataclasses.dataclass(frozen=True)
class ImportSettings:
    """What the table does not say: the body's known constants and how to split.

    Attributes:
        mass: dry mass ``M`` [kg]. area: reference area ``A`` [m²]. rho: fluid density [kg/m³].
        volume: displaced volume ``V`` [m³] (default ``M / rho``, a floating body).
        split: fractions of the trajectories for train, val and test (summing to 1, each > 0:
            every split gets at least one trajectory).
        seed: seed of the split's permutation.
        time_dependent: whether models may let the flow depend on time.
        smoother: the velocity estimator: a key of :data:`~fhnn.data.derivatives.SMOOTHERS`, or
            ``"auto"`` (the spline up to :data:`~fhnn.data.derivatives.AUTO_SPLINE_ROWS` rows,
            the Kalman smoother above; :func:`~fhnn.data.derivatives.choose_smoother`).
        max_gap: a track is split into pieces where two samples are more than this many seconds
            apart (``inf``: never); ``None``: where they are more than :data:`GAP_STEPS` times
            the track's median step apart (:func:`split_at_gaps`).
        outlier_sigmas: a position more than this many noise levels from the cubic through its
            neighbours is dropped as a glitch (:func:`drop_outliers`); ``None``: every sample kept.
        forcing_hold: how a separate forcing table reads between its rows: ``"linear"``
            (interpolated at the samples) or ``"previous"`` (each row's force held until the next
            row: the change times are kept, :attr:`~fhnn.data.dataset.Split.switch`).
    """

    mass: float
    area: float
    rho: float = 1000.0
    volume: float | None = None
    split: tuple[float, float, float] = (0.7, 0.2, 0.1)
    seed: int = 0
    time_dependent: bool = False
    smoother: str = AUTO
    max_gap: float | None = None
    outlier_sigmas: float | None = OUTLIER_SIGMAS
    forcing_hold: str = "linear"

    def __post_init__(self) -> None:
        choose_smoother(self.smoother, 0)  # an unknown name is refused here
        check_forcing_hold(self.forcing_hold)
        if self.outlier_sigmas is not None and not (self.outlier_sigmas > 0):
            raise ConfigError(f"--outliers must be a number > 0 (or off), got {self.outlier_sigmas!r}")
        if self.max_gap is not None and not (self.max_gap > 0):
            raise ConfigError(f"--max-gap must be a number of seconds > 0 (or auto), got {self.max_gap!r}")
        for name in ("mass", "area", "rho"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ConfigError(f"--{name} must be a number > 0, got {value!r}")
        if self.volume is not None and not (np.isfinite(self.volume) and self.volume > 0):
            raise ConfigError(f"--volume must be a number > 0, got {self.volume!r}")
        if (
            len(self.split) != 3
            or any(not (f >= 0) for f in self.split)
            or not np.isclose(sum(self.split), 1)
        ):
            raise ConfigError(
                f"--split must be three fractions summing to 1 (e.g. 70/20/10), got {self.split}"
            )
        if min(self.split) == 0:  # split_counts would give the split one trajectory regardless
            raise ConfigError(
                f"--split must give train, val and test each a share > 0 (each gets at least one "
                f"trajectory), got {self.split}"
            )
        if self.seed < 0:
            raise ConfigError(f"--seed must be >= 0, got {self.seed}")


def parse_split(text: str) -> tuple[float, float, float]:
    """``"70/20/10"`` → ``(0.7, 0.2, 0.1)``; the parts are percentages summing to 100."""
    parts = text.split("/")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or any(not (v >= 0) for v in values) or not np.isclose(sum(values), 100):
        raise ConfigError(f"--split must be three percentages summing to 100, like 70/20/10; got {text!r}")
    return (values[0] / 100, values[1] / 100, values[2] / 100)


def split_counts(n: int, fractions: tuple[float, float, float]) -> tuple[int, int, int]:
    """Trajectories per split: at least one each, the rest by ``fractions`` (largest remainders)."""
    if n < 3:
        raise DataFormatError(f"the table has {n} trajectory(ies); train, val and test need at least 3")
    exact = np.asarray(fractions) * n
    counts = np.maximum(np.floor(exact).astype(int), 1)
    while counts.sum() > n:
        counts[int(np.argmax(counts))] -= 1
    order = np.argsort(-(exact - np.floor(exact)), kind="stable")
    i = 0
    while counts.sum() < n:
        counts[order[i % 3]] += 1
        i += 1
    return int(counts[0]), int(counts[1]), int(counts[2])


def _pad(a: np.ndarray, size: int) -> np.ndarray:
    """``a`` ``(n, ...)`` extended to ``size`` rows by repeating its last row."""
    return np.concatenate([a, np.repeat(a[-1:], size - a.shape[0], axis=0)], axis=0)


def _split_of(items: list[dict[str, np.ndarray]]) -> Split:
    size = max(item["t"].size for item in items)
    t = np.stack(
        [
            np.r_[item["t"], item["t"][-1] + PAD_STEP * np.arange(1, size - item["t"].size + 1)]
            for item in items
        ]
    )
    stack = lambda key: np.stack([_pad(item[key], size) for item in items])  # noqa: E731
    states = stack("states")
    derivs = stack("derivs")
    for i, item in enumerate(items):  # padding has no motion
        derivs[i, item["t"].size :] = 0.0
    lengths = np.asarray([item["t"].size for item in items], dtype=np.int64)
    return Split(
        t=t,
        states=states,
        states_clean=states.copy(),
        derivs=derivs,
        forces=stack("forces"),
        actuation=np.zeros((len(items), 2, 3, 3)),
        lengths=lengths,
        switch=within_intervals(t, stack("switch")) if "switch" in items[0] else None,
    )


def table_to_dataset(
    table: Table,
    settings: ImportSettings,
    source: str = "",
    *,
    time_unit: str = "s",
    forcing: dict[str | None, tuple[np.ndarray, np.ndarray]] | None = None,
) -> Dataset:
    """A data set of ``table``'s trajectories (see the module docstring).

    Times are shifted so that the earliest sample of the table is at ``t = 0`` (the shift is kept
    in the ``import`` record); ``states_clean`` holds the observed states (the truth is unknown),
    ``derivs`` the estimated ``(vx, vy, ax, ay)``. ``forcing``: the known forces as a separate
    table on the table's clock (:func:`~fhnn.data.table.read_forcing`; a table with ``Fx, Fy``
    columns takes none), read at the samples as ``settings.forcing_hold`` says
    (:func:`forcing_at_samples`).

    Raises:
        ConfigError: forces both in the table and in ``forcing``.
        DataFormatError: too few trajectories, non-finite velocity estimates, or a forcing table
            that misses a trajectory or changes more than once between two held samples.
    """
    if forcing is not None and table.trajectories[0].force is not None:
        raise ConfigError(
            "the table has Fx, Fy columns: give the known forces there or in --forcing, not both"
        )
    cut = split_at_gaps(table.trajectories, settings.max_gap)
    trajs = cut.pieces
    kept = int(np.unique(cut.track).size)
    if kept < 3:
        split_counts(len(table.trajectories), settings.split)  # too few tracks in the table: refused there
        raise DataFormatError(
            f"{kept} of the table's {len(table.trajectories)} trajectories keep a piece of at least "
            f"{MIN_SAMPLES} samples between gaps longer than --max-gap; train, val and test need at least 3"
        )
    has_vel = trajs[0].vel is not None
    has_force = trajs[0].force is not None or forcing is not None
    t0 = min(float(tr.t[0]) for tr in trajs)
    glitches: list[tuple[str, float]] = []
    trajs, pos_noise, outliers, touched = without_outliers(trajs, settings.outlier_sigmas, glitches)
    series = position_series(trajs)
    smoother = choose_smoother(settings.smoother, table.rows)
    vel_noise = vel_error = None
    if has_vel:  # the acceleration of each recorded velocity
        velocities = [(tr.t, tr.vel[:, k]) for tr in trajs for k in range(2)]
        vel_noise = noise_level(velocities)
        rates = smooth_derivatives(velocities, vel_noise, smoother)
    else:  # (velocity, acceleration) of each position
        rates = smooth_derivatives(series, pos_noise, smoother)
        vel_error = derivative_error(series, pos_noise, smoother, seed=settings.seed)
    items = []
    held = forcing is not None and settings.forcing_hold == "previous"
    for i, tr in enumerate(trajs):
        vel = np.empty_like(tr.pos)
        acc = np.empty_like(tr.pos)
        for k in range(2):
            first, second = rates[2 * i + k]
            if has_vel:
                vel[:, k], acc[:, k] = tr.vel[:, k], first
            else:
                vel[:, k], acc[:, k] = first, second
        item = {
            "t": tr.t - t0,
            "states": np.concatenate([tr.pos, vel], axis=1),
            "derivs": np.concatenate([vel, acc], axis=1),
            "forces": tr.force if tr.force is not None else np.zeros_like(tr.pos),
        }
        if forcing is not None:
            track = table.trajectories[cut.track[i]].traj_id
            rows = forcing.get(track, forcing.get(None))
            if rows is None:
                raise DataFormatError(f"the forcing table has no rows for trajectory {track!r}")
            item["forces"], switch = forcing_at_samples(tr.t, rows, settings.forcing_hold, tr.traj_id)
            if held:
                item["switch"] = switch - t0
        items.append(item)
    bad = [
        tr.traj_id for tr, item in zip(trajs, items, strict=True) if not np.all(np.isfinite(item["derivs"]))
    ]
    if bad:  # never write what the estimator could not give
        raise DataFormatError(
            f"velocity estimates are not finite for trajectory {bad[0]!r} ({len(bad)} in all)"
        )
    # the split permutes the table's tracks: the pieces of a track split at gaps stay together
    tracks = np.unique(cut.track)
    counts = split_counts(tracks.size, settings.split)
    perm = tracks[np.random.default_rng(settings.seed).permutation(tracks.size)]
    bounds = np.cumsum((0, *counts))
    members = {
        name: np.flatnonzero(np.isin(cut.track, perm[bounds[k] : bounds[k + 1]]))
        for k, name in enumerate(SPLITS)
    }
    splits = {name: _split_of([items[i] for i in members[name]]) for name in SPLITS}
    steps = np.concatenate([np.diff(tr.t) for tr in trajs])
    warnings = _clock_warnings(trajs, steps)
    measured = ["positions", *(["velocities"] if has_vel else []), *(["forces"] if has_force else [])]
    volume = settings.volume if settings.volume is not None else settings.mass / settings.rho
    ids = {name: [trajs[i].traj_id for i in members[name]] for name in SPLITS}
    record = {
        "source": source,
        "rows": table.rows,
        "dropped_rows": table.dropped,
        "trajectories": len(trajs),
        "tracks": len(table.trajectories),
        "max_gap": settings.max_gap,
        "gap_steps": GAP_STEPS if settings.max_gap is None else None,
        "gaps_split": cut.gaps,
        "tracks_split": cut.split_tracks,
        "short_pieces_dropped": cut.short_pieces,
        "short_piece_rows": cut.short_rows,
        "outlier_sigmas": settings.outlier_sigmas,
        "outliers_dropped": outliers,
        "outlier_trajectories": touched,
        # where (trajectory or piece, time on the table's clock [s]): the first OUTLIERS_LISTED
        "outliers_at": [[traj, time] for traj, time in glitches[:OUTLIERS_LISTED]],
        "time_offset": t0,
        "time_origin": table.time_origin,
        "time_unit": time_unit,
        "position_noise": pos_noise,
        "velocity_noise": vel_noise,
        "velocity_error": vel_error,
        "velocity": "measured" if has_vel else f"{smoother} smoother at the noise level (RMS residual = σ)",
        "smoother": smoother,
        "step_median": float(np.median(steps)),
        "step_range": [float(steps.min()), float(steps.max())],
        "traj_ids": ids,
        "warnings": warnings,
        "forcing": None if forcing is None else {"hold": settings.forcing_hold, "rows": _rows(forcing)},
    }
    return Dataset(
        scenario=IMPORTED,
        scenario_params={"time_dependent": bool(settings.time_dependent)},
        body_params={"M": settings.mass, "rho": settings.rho, "A": settings.area, "V": volume},
        seed=int(settings.seed),
        dt=float(np.median(steps)),
        actuation="recorded" if has_force else "none",
        obs_noise=float(pos_noise),
        version=__version__,
        splits=splits,
        extra={"measured": measured, "import": record},
    )


def _rows(forcing: dict[str | None, tuple[np.ndarray, np.ndarray]]) -> int:
    return int(sum(t.size for t, _ in forcing.values()))


def forcing_at_samples(
    t: np.ndarray, rows: tuple[np.ndarray, np.ndarray], hold: str, name: str
) -> tuple[np.ndarray, np.ndarray]:
    """A forcing table's forces at a trajectory's samples.

    Args:
        t: the trajectory's sample times [s], shape ``(n,)``, on the table's clock.
        rows: the forcing rows' times [s] ``(m,)`` (increasing) and forces [N] ``(m, 2)``.
        hold: ``"linear"``: the forces interpolated at ``t`` (the rows must span the samples);
            ``"previous"``: each row's force held until the next row (a row at or before the
            first sample is needed).
        name: the trajectory's id, for errors.

    Returns:
        ``(forces (n, 2), switch (n,))``: the force in effect at each sample and, for each
        interval ``k``, when inside it the held force changes (``t[k + 1]`` where it changes at
        the next sample or not at all; :attr:`~fhnn.data.dataset.Split.switch`; unread under
        ``"linear"``).

    Raises:
        DataFormatError: rows that do not cover the trajectory, or a held force that changes more
            than once between two samples.
    """
    tf, force = rows
    switch = np.r_[t[1:], t[-1]]
    if tf[0] > t[0]:
        raise DataFormatError(
            f"the forcing table starts at {tf[0]:g} s, after the first sample of trajectory {name!r} "
            f"({t[0]:g} s)"
        )
    if hold == "linear":
        if tf[-1] < t[-1]:
            raise DataFormatError(
                f"the forcing table ends at {tf[-1]:g} s, before the last sample of trajectory {name!r} "
                f"({t[-1]:g} s); --forcing-hold previous holds its last row"
            )
        return np.stack([np.interp(t, tf, force[:, 0]), np.interp(t, tf, force[:, 1])], axis=1), switch
    at_samples = force[np.searchsorted(tf, t, side="right") - 1]
    changes = tf[np.flatnonzero(np.any(force[1:] != force[:-1], axis=1)) + 1]
    k = np.searchsorted(t, changes, side="left") - 1  # t[k] < change <= t[k + 1]
    inside = (k >= 0) & (k < t.size - 1)
    inside[inside] &= changes[inside] < t[k[inside] + 1]  # a change at a sample is at the sample
    k, changes = k[inside], changes[inside]
    twice = np.flatnonzero(np.diff(k) == 0)
    if twice.size:
        j = int(k[twice[0]])
        raise DataFormatError(
            f"the held force changes more than once between the samples at {t[j]:g} and {t[j + 1]:g} s "
            f"of trajectory {name!r}; held forcing takes one change per sample interval "
            "(or use --forcing-hold linear)"
        )
    switch[k] = changes
    return at_samples, switch


#: A median step [s] above which, with a median speed below :data:`SLOW_SPEED` [m/s], the times
#: look like milliseconds read as seconds (a tank's tracker at 10 Hz: steps of 100, speeds 1e-4).
LONG_STEP = 10.0
SLOW_SPEED = 1e-3


def _clock_warnings(trajs: list[Trajectory], steps: np.ndarray) -> list[str]:
    """What looks wrong with the table's clock: a warning each (empty: nothing)."""
    speeds = np.concatenate([np.hypot(*np.diff(tr.pos, axis=0).T) / np.diff(tr.t) for tr in trajs])
    step, speed = float(np.median(steps)), float(np.median(speeds))
    if step > LONG_STEP and speed < SLOW_SPEED:
        return [
            f"the median step is {step:.4g} s and the median speed {speed:.3g} m/s: if the times are "
            "milliseconds (or another unit), import again with --time-unit"
        ]
    return []
