"""Trajectory data sets in memory and in HDF5 files (docs/spec.md §3).

File layout (``format = "fhnn-trajectories"``, ``format_version = 2``)::

    /                 attrs: format, format_version, scenario, seed, scenario_params (JSON),
                             body_params (JSON), dt, actuation, obs_noise, version, ...
    /{train,val,test}/t             (T,)         s, starting at 0 (one grid for every trajectory)
                                    or (N, T)    s, each trajectory's own times (irregular data)
    /{train,val,test}/lengths       (N,)         optional: samples of each trajectory (padded after)
    /{train,val,test}/states        (N, T, 4)    observed (x, y, vx, vy)
    /{train,val,test}/states_clean  (N, T, 4)    noise-free truth
    /{train,val,test}/derivs        (N, T, 4)    true ds/dt at the clean states
    /{train,val,test}/forces        (N, T, 2)    F_ext at each sample time [N]
    /{train,val,test}/actuation     (N, 2, 3, 3) per axis and mode: (amplitude, frequency, phase)
    /{train,val,test}/switch        (N, T)       optional: held forcing's change time in each
                                                 sample interval [s] (Split.switch)

Version 2 adds what imported measurements need (version 1 files, written before, are read as
they are): per-trajectory times ``t`` of shape ``(N, T)`` and ``lengths`` for trajectories of
unequal length — samples past a trajectory's length are padding (times continue increasing, the
other arrays repeat its last sample) that no loss or metric reads — and the root attribute
``measured`` (JSON list, a subset of :data:`MEASURABLE`) naming which fields were recorded; the
others were estimated (:mod:`fhnn.data.table`). A data set without it was simulated: every field
is the truth. An imported data set has ``scenario = "imported"`` and ``body_params`` holding the
known constants ``M, rho, A, V`` only: its flow and coefficients are what a model is to find.

:func:`write_dataset` writes to a temporary file beside the target and renames it, so a failure
never leaves a partial file. :func:`read_dataset` checks format, version, groups, shapes and values
and raises :class:`~fhnn.errors.DataFormatError` with a one-line reason otherwise.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from fhnn.errors import DataFormatError
from fhnn.files import atomic_output, check_input_file
from fhnn.physics.actuation import force_residual
from fhnn.physics.body import Body
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.scenarios import Scenario, scenario_class

FORMAT = "fhnn-trajectories"
FORMAT_VERSION = 2
#: The oldest format version this fhnn reads.
OLDEST_FORMAT_VERSION = 1
#: ``scenario`` of a data set made from a user's measurements (no known flow or coefficients).
IMPORTED = "imported"
#: Fields a data set may have recorded rather than estimated (attribute ``measured``).
MEASURABLE = ("positions", "velocities", "forces", "derivatives")
SPLITS = ("train", "val", "test")
ARRAYS = ("t", "states", "states_clean", "derivs", "forces", "actuation")
REQUIRED_ATTRS = (
    "format",
    "format_version",
    "scenario",
    "seed",
    "scenario_params",
    "body_params",
    "dt",
    "actuation",
    "obs_noise",
    "version",
)


def samples_until(t: np.ndarray, until: float) -> int:
    """How many of the increasing sample times ``t`` [s] lie at or before ``until`` [s] (to 1e-9 s)."""
    return int(np.searchsorted(t, until - 1e-9)) + 1


def masses_are_gauge(known_forcing: bool, constants: dict[str, Any]) -> bool:
    """Whether added masses are a free gauge of data (:attr:`Dataset.masses_are_gauge`).

    Args:
        known_forcing: whether the data carry known, non-zero external forces.
        constants: the body's ``M`` [kg], ``rho`` [kg/m³], ``V`` [m³] and ``fluid_inertia``.
    """
    neutral = np.isclose(constants["rho"] * constants["V"], constants["M"], rtol=1e-9, atol=0.0)
    return not known_forcing and (not constants["fluid_inertia"] or bool(neutral))


@dataclasses.dataclass(frozen=True, eq=False)
class Split:
    """One split of a data set: ``N`` trajectories of (up to) ``T`` samples.

    Attributes:
        t: sample times [s], shape ``(T,)`` (one grid for every trajectory) or ``(N, T)`` (each
            trajectory's own, strictly increasing along each row, padding included).
        states: observed states, shape ``(N, T, 4)``.
        states_clean: noise-free states, shape ``(N, T, 4)``.
        derivs: true ``ds/dt`` at the clean states, shape ``(N, T, 4)``.
        forces: ``F_ext`` [N] at the sample times, shape ``(N, T, 2)``.
        actuation: forcing parameters, shape ``(N, 2, 3, 3)``.
        lengths: samples of each trajectory, shape ``(N,)``, or ``None``: all ``T``. The samples
            past a trajectory's length are padding (see the module docstring).
        switch: ``None`` (the forcing is interpolated linearly between samples), or held
            forcing: the force is ``forces[:, k]`` from sample ``k`` up to ``switch[:, k]`` [s] and
            ``forces[:, k + 1]`` from there to sample ``k + 1`` (``t[k] ≤ switch[k] ≤ t[k + 1]``;
            the last entry and padding: the sample's own time), shape ``(N, T)``.
    """

    t: np.ndarray
    states: np.ndarray
    states_clean: np.ndarray
    derivs: np.ndarray
    forces: np.ndarray
    actuation: np.ndarray
    lengths: np.ndarray | None = None
    switch: np.ndarray | None = None

    @property
    def n_traj(self) -> int:
        return int(self.states.shape[0])

    @property
    def n_times(self) -> int:
        """``T``: samples per trajectory (the longest trajectory's, where lengths differ)."""
        return int(self.t.shape[-1])

    @property
    def regular(self) -> bool:
        """Whether every trajectory is sampled at the same times ``t`` ``(T,)``."""
        return self.t.ndim == 1 and self.lengths is None

    @property
    def times(self) -> np.ndarray:
        """Each trajectory's sample times [s], shape ``(N, T)`` (padding included)."""
        return np.broadcast_to(self.t, (self.n_traj, self.n_times))

    @property
    def sample_counts(self) -> np.ndarray:
        """Samples of each trajectory, shape ``(N,)``."""
        if self.lengths is None:
            return np.full(self.n_traj, self.n_times)
        return np.asarray(self.lengths, dtype=int)

    @property
    def mask(self) -> np.ndarray:
        """True at real samples, false at padding, shape ``(N, T)``."""
        return np.arange(self.n_times)[None, :] < self.sample_counts[:, None]

    @property
    def end_times(self) -> np.ndarray:
        """Each trajectory's last sample time [s], shape ``(N,)``."""
        return self.times[np.arange(self.n_traj), self.sample_counts - 1]

    @property
    def duration(self) -> float:
        """The longest trajectory's duration [s]."""
        return float(np.max(self.end_times - self.times[:, 0]))

    def arrays(self) -> dict[str, np.ndarray]:
        out = {name: getattr(self, name) for name in ARRAYS}
        if self.lengths is not None:
            out["lengths"] = np.asarray(self.lengths)
        if self.switch is not None:
            out["switch"] = np.asarray(self.switch)
        return out

    def subset(self, index: Any) -> Split:
        """The trajectories ``index`` (anything NumPy can index the first axis with)."""
        t = self.t if self.t.ndim == 1 else self.t[index]
        return Split(t=t, **{k: v[index] for k, v in self.arrays().items() if k != "t"})

    @functools.cached_property
    def force_residual(self) -> np.ndarray:
        """The recorded ``forces`` less the sinusoids of ``actuation`` at ``t``, shape ``(N, T, 2)``
        [N]: zero for simulated data, the recorded forces themselves where the forcing is known
        only as samples (all amplitudes zero). Models take ``F(t)`` from both
        (:func:`~fhnn.physics.actuation.forcing`)."""
        return force_residual(self.actuation, self.times, self.forces)


@dataclasses.dataclass(frozen=True, eq=False)
class Dataset:
    """A data set: metadata and its train / val / test splits.

    Attributes:
        scenario: registered scenario name.
        scenario_params: every parameter of the scenario (incl. drawn random modes).
        body_params: the body's constants and coefficient laws (:meth:`Body.to_dict`).
        seed: the seed the data set was drawn from.
        dt: sampling interval [s].
        actuation: "random" or "none".
        obs_noise: standard deviation of the observation noise.
        version: fhnn version that wrote it.
        splits: ``{"train": Split, "val": Split, "test": Split}``.
        extra: further attributes (solver tolerances, redraw counts, ...).
    """

    scenario: str
    scenario_params: dict[str, Any]
    body_params: dict[str, Any]
    seed: int
    dt: float
    actuation: str
    obs_noise: float
    version: str
    splits: dict[str, Split]
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)

    def __getitem__(self, split: str) -> Split:
        if split not in self.splits:
            raise DataFormatError(f"no split {split!r}; have {', '.join(self.splits)}")
        return self.splits[split]

    @property
    def train(self) -> Split:
        return self["train"]

    @property
    def val(self) -> Split:
        return self["val"]

    @property
    def test(self) -> Split:
        return self["test"]

    @property
    def imported(self) -> bool:
        """Whether the data are a user's measurements (:data:`IMPORTED`): no known flow or body."""
        return self.scenario == IMPORTED

    @property
    def centre(self) -> np.ndarray:
        """The point [m], shape ``(2,)``, that models measure positions from: the mean of the
        training positions for imported data (a table's origin is wherever its tracker put it),
        the coordinate origin for a simulated scenario (its flow and coefficient laws are
        written about it)."""
        if not self.imported:
            return np.zeros(2)
        split = self.train
        return np.mean(split.states[split.mask][:, :2], axis=0)

    @property
    def measured(self) -> tuple[str, ...]:
        """The fields recorded (the others were estimated); all of :data:`MEASURABLE` for
        simulated data."""
        return tuple(self.extra.get("measured", MEASURABLE))

    @property
    def time_dependent(self) -> bool:
        """Whether the flow may depend on time (imported data: as the user said on import)."""
        if self.imported:
            return bool(self.scenario_params.get("time_dependent", False))
        return bool(self.scenario_object().time_dependent)

    def constants(self) -> dict[str, Any]:
        """The body's known constants: ``M`` [kg], ``rho`` [kg/m³], ``A`` [m²], ``V`` [m³] and
        ``fluid_inertia`` (whether the Morison fluid-inertia force acts)."""
        p = self.body_params
        return {
            "M": float(p["M"]),
            "rho": float(p["rho"]),
            "A": float(p["A"]),
            "V": float(p.get("V", float(p["M"]) / float(p["rho"]))),
            "fluid_inertia": bool(p.get("fluid_inertia", False)),
        }

    @property
    def known_forcing(self) -> bool:
        """Whether the training data carry recorded, non-zero external forces: only then are the
        added masses and drag coefficients determined, not just their ratios ``c / (M + m_a)``."""
        train = self.train
        return "forces" in self.measured and bool(np.any(train.forces[train.mask] != 0))

    @property
    def masses_are_gauge(self) -> bool:
        """Whether the added masses are a free gauge of these data: no known forcing, and no
        Morison fluid inertia or a neutrally buoyant body (``ρV = M``). A body's acceleration is
        then ``F_h,i / (M + m_a,i)`` (plus ``Du/Dt`` where ``ρV = M``), so scaling ``M + m_a`` and
        the drag together by any factor, even one that varies with ``(r, σ)``, changes nothing."""
        return masses_are_gauge(self.known_forcing, self.constants())

    def _truth(self, what: str) -> None:
        if self.imported:
            raise DataFormatError(f"{what} is unknown for imported data (no ground truth)")

    def scenario_object(self) -> Scenario:
        """The scenario (with its stored parameters) that generated the data."""
        self._truth("the scenario")
        return scenario_class(self.scenario).from_dict(self.scenario_params)

    def body(self) -> Body:
        """The ground-truth body, rebuilt from ``body_params``."""
        self._truth("the body's coefficients")
        return Body.from_dict(self.body_params)

    def equations(self) -> EquationsOfMotion:
        """The ground-truth equations of motion."""
        return EquationsOfMotion.of(self.scenario_object().flow(), self.body())

    def attrs(self) -> dict[str, Any]:
        """Root attributes as written to HDF5."""
        out: dict[str, Any] = {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "scenario": self.scenario,
            "seed": int(self.seed),
            "scenario_params": json.dumps(self.scenario_params, sort_keys=True),
            "body_params": json.dumps(self.body_params, sort_keys=True),
            "dt": float(self.dt),
            "actuation": self.actuation,
            "obs_noise": float(self.obs_noise),
            "version": self.version,
        }
        for key, value in self.extra.items():
            out[key] = json.dumps(value) if isinstance(value, dict | list) else value
        return out


def write_dataset(dataset: Dataset, path: str | os.PathLike[str]) -> Path:
    """Write ``dataset`` to ``path`` (HDF5) atomically; returns the path."""
    with atomic_output(path) as tmp:
        with h5py.File(tmp, "w") as f:
            for key, value in dataset.attrs().items():
                f.attrs[key] = value
            for name in SPLITS:
                group = f.create_group(name)
                for key, array in dataset[name].arrays().items():
                    dtype = np.int64 if key == "lengths" else np.float64
                    group.create_dataset(key, data=np.asarray(array, dtype=dtype))
    return Path(path)


def read_dataset(path: str | os.PathLike[str]) -> Dataset:
    """Read and check an fhnn data set; raises :class:`DataFormatError` naming what is wrong."""
    path = check_input_file(path, "a data file")
    try:
        f = h5py.File(path, "r")
    except OSError:
        raise DataFormatError(f"{path}: not a readable HDF5 file (truncated or another format)") from None
    try:
        with f:
            return _read_open(path, f)
    except (OSError, KeyError, ValueError, TypeError) as exc:
        if isinstance(exc, DataFormatError):
            raise
        raise DataFormatError(f"{path}: unreadable or corrupted data set ({exc})") from None


def _read_open(path: Path, f: h5py.File) -> Dataset:
    fmt = f.attrs.get("format")
    if fmt is None:
        raise DataFormatError(f"{path}: not an fhnn data set (no 'format' attribute)")
    if _text(fmt) != FORMAT:
        raise DataFormatError(f"{path}: not an fhnn data set (format is {_text(fmt)!r}, expected {FORMAT!r})")
    version = _decode(f.attrs.get("format_version"))
    if not isinstance(version, int) or not OLDEST_FORMAT_VERSION <= version <= FORMAT_VERSION:
        raise DataFormatError(
            f"{path}: unsupported format_version {version!r} (this fhnn reads "
            f"{OLDEST_FORMAT_VERSION} to {FORMAT_VERSION})"
        )
    missing = [k for k in REQUIRED_ATTRS if k not in f.attrs]
    if missing:
        raise DataFormatError(f"{path}: missing attribute(s) {', '.join(missing)}")
    attrs = {k: _text(v) if isinstance(v, bytes | str) else v for k, v in f.attrs.items()}
    try:
        scenario_params = json.loads(attrs["scenario_params"])
        body_params = json.loads(attrs["body_params"])
    except (json.JSONDecodeError, TypeError) as exc:
        raise DataFormatError(f"{path}: scenario_params/body_params are not valid JSON ({exc})") from None
    splits = {name: _read_split(path, f, name) for name in SPLITS}
    extra = {k: _decode(v) for k, v in attrs.items() if k not in REQUIRED_ATTRS}
    dataset = Dataset(
        scenario=str(attrs["scenario"]),
        scenario_params=scenario_params,
        body_params=body_params,
        seed=int(attrs["seed"]),
        dt=float(attrs["dt"]),
        actuation=str(attrs["actuation"]),
        obs_noise=float(attrs["obs_noise"]),
        version=str(attrs["version"]),
        splits=splits,
        extra=extra,
    )
    if dataset.dt <= 0:
        raise DataFormatError(f"{path}: dt must be > 0, got {dataset.dt}")
    unknown = set(dataset.measured) - set(MEASURABLE)
    if unknown or "positions" not in dataset.measured:
        raise DataFormatError(f"{path}: 'measured' must list positions and only {', '.join(MEASURABLE)}")
    try:
        constants = dataset.constants()
        if not all(constants[k] > 0 for k in ("M", "rho", "A", "V")):
            raise ValueError(f"M, rho, A and V must be > 0, got {constants}")
        if not dataset.imported:
            dataset.scenario_object()
            dataset.body()
    except Exception as exc:  # a scenario or body that cannot be rebuilt is a format error
        raise DataFormatError(f"{path}: bad scenario or body metadata ({exc})") from None
    return dataset


def _read_split(path: Path, f: h5py.File, name: str) -> Split:
    if name not in f or not isinstance(f[name], h5py.Group):
        raise DataFormatError(f"{path}: missing group /{name}")
    group = f[name]
    arrays = {}
    for key in ARRAYS:
        if key not in group:
            raise DataFormatError(f"{path}: missing dataset /{name}/{key}")
        arrays[key] = np.asarray(group[key][()], dtype=np.float64)
    t = arrays["t"]
    if t.ndim not in (1, 2) or t.shape[-1] < 2:
        raise DataFormatError(f"{path}: /{name}/t must have shape (T,) or (N, T) with T >= 2, got {t.shape}")
    T = t.shape[-1]
    states_shape = arrays["states"].shape
    if len(states_shape) != 3 or states_shape[0] < 1:
        raise DataFormatError(
            f"{path}: /{name}/states has shape {states_shape}, expected (N, {T}, 4) with N >= 1"
        )
    n = states_shape[0]
    expected = {
        "t": (n, T) if t.ndim == 2 else (T,),
        "states": (n, T, 4),
        "states_clean": (n, T, 4),
        "derivs": (n, T, 4),
        "forces": (n, T, 2),
        "actuation": (n, 2, 3, 3),
    }
    if "lengths" in group:
        lengths = np.asarray(group["lengths"][()])
        if lengths.shape != (n,) or not np.issubdtype(lengths.dtype, np.integer):
            raise DataFormatError(
                f"{path}: /{name}/lengths must be {n} integers, got {lengths.dtype} {lengths.shape}"
            )
        if np.any(lengths < 2) or np.any(lengths > T):
            raise DataFormatError(f"{path}: /{name}/lengths must lie in [2, {T}]")
        arrays["lengths"] = lengths.astype(np.int64)
    if "switch" in group:
        arrays["switch"] = np.asarray(group["switch"][()], dtype=np.float64)
        expected["switch"] = (n, T)
    for key, shape in expected.items():
        if arrays[key].shape != shape:
            raise DataFormatError(f"{path}: /{name}/{key} has shape {arrays[key].shape}, expected {shape}")
    for key, array in arrays.items():
        if not np.all(np.isfinite(array)):
            count = int(np.sum(~np.isfinite(array)))
            raise DataFormatError(f"{path}: /{name}/{key} has {count} NaN or infinite value(s)")
    if np.any(np.diff(t, axis=-1) <= 0):
        raise DataFormatError(f"{path}: /{name}/t is not strictly increasing")
    split = Split(**arrays)
    _check_switch(split, f"{path}: /{name}/switch")
    check_forcing(split, f"{path}: /{name}")
    return split


def _check_switch(split: Split, where: str) -> None:
    """Raise :class:`DataFormatError` if a held forcing's change time lies outside its interval."""
    if split.switch is None:
        return
    times, switch = split.times, split.switch
    off = ((switch[:, :-1] < times[:, :-1]) | (switch[:, :-1] > times[:, 1:])) & split.mask[:, 1:]
    if np.any(off):
        i, k = np.argwhere(off)[0]
        raise DataFormatError(
            f"{where} of trajectory {i} is {switch[i, k]:g} s, outside its sample interval "
            f"[{times[i, k]:g}, {times[i, k + 1]:g}] s"
        )


def within_intervals(times: np.ndarray, switch: np.ndarray) -> np.ndarray:
    """``switch`` ``(N, T)`` clipped into each sample interval ``[t[k], t[k + 1]]`` of ``times``
    ``(N, T)`` (the last entry to its own time): what padding repeated from a real sample
    becomes (no change inside a padded interval)."""
    upper = np.concatenate([times[:, 1:], times[:, -1:]], axis=1)
    return np.clip(switch, times, upper)


def check_forcing(split: Split, where: str) -> None:
    """Raise :class:`DataFormatError` if a trajectory with actuation parameters records forces
    that are not those parameters' sinusoids (a trajectory with all amplitudes zero may record any
    forces: they are then its forcing, interpolated between samples)."""
    parametric = np.any(split.actuation[..., 0] != 0.0, axis=(1, 2))
    off = np.abs(split.force_residual).max(axis=(1, 2)) > 0
    bad = np.flatnonzero(parametric & off)
    if bad.size:
        i = int(bad[0])
        k = int(np.abs(split.force_residual[i]).max(axis=1).argmax())
        raise DataFormatError(
            f"{where}/forces disagree with /actuation for {bad.size} trajectory(ies), first trajectory "
            f"{i} at t = {split.times[i, k]:g} s (recorded {split.forces[i, k].tolist()} N, actuation gives "
            f"{(split.forces[i, k] - split.force_residual[i, k]).tolist()} N)"
        )


def _text(value: Any) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _decode(value: Any) -> Any:
    if isinstance(value, str) and value[:1] in "[{":
        try:
            return json.loads(value)
        except json.JSONDecodeError:
            return value
    if isinstance(value, np.generic):
        return value.item()
    return value
