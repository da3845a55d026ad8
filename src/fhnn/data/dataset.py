"""Trajectory data sets in memory and in HDF5 files (SPEC §3).

File layout (``format = "fhnn-trajectories"``, ``format_version = 1``)::

    /                 attrs: format, format_version, scenario, seed, scenario_params (JSON),
                             body_params (JSON), dt, actuation, obs_noise, version, ...
    /{train,val,test}/t             (T,)         s, starting at 0
    /{train,val,test}/states        (N, T, 4)    observed (x, y, vx, vy)
    /{train,val,test}/states_clean  (N, T, 4)    noise-free truth
    /{train,val,test}/derivs        (N, T, 4)    true ds/dt at the clean states
    /{train,val,test}/forces        (N, T, 2)    F_ext at each sample time [N]
    /{train,val,test}/actuation     (N, 2, 3, 3) per axis and mode: (amplitude, frequency, phase)

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
from fhnn.files import atomic_output
from fhnn.physics.actuation import force_residual
from fhnn.physics.body import Body
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.scenarios import Scenario, scenario_class

FORMAT = "fhnn-trajectories"
FORMAT_VERSION = 1
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


@dataclasses.dataclass(frozen=True, eq=False)
class Split:
    """One split of a data set: ``N`` trajectories sampled at the ``T`` times ``t``.

    Attributes:
        t: sample times [s], shape ``(T,)``.
        states: observed states, shape ``(N, T, 4)``.
        states_clean: noise-free states, shape ``(N, T, 4)``.
        derivs: true ``ds/dt`` at the clean states, shape ``(N, T, 4)``.
        forces: ``F_ext`` [N] at the sample times, shape ``(N, T, 2)``.
        actuation: forcing parameters, shape ``(N, 2, 3, 3)``.
    """

    t: np.ndarray
    states: np.ndarray
    states_clean: np.ndarray
    derivs: np.ndarray
    forces: np.ndarray
    actuation: np.ndarray

    @property
    def n_traj(self) -> int:
        return int(self.states.shape[0])

    @property
    def n_times(self) -> int:
        return int(self.t.shape[0])

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def arrays(self) -> dict[str, np.ndarray]:
        return {name: getattr(self, name) for name in ARRAYS}

    def subset(self, index: Any) -> Split:
        """The trajectories ``index`` (anything NumPy can index the first axis with)."""
        return Split(t=self.t, **{k: v[index] for k, v in self.arrays().items() if k != "t"})

    @functools.cached_property
    def force_residual(self) -> np.ndarray:
        """The recorded ``forces`` less the sinusoids of ``actuation`` at ``t``, shape ``(N, T, 2)``
        [N]: zero for simulated data, the recorded forces themselves where the forcing is known
        only as samples (all amplitudes zero). Models take ``F(t)`` from both
        (:func:`~fhnn.physics.actuation.forcing`)."""
        return force_residual(self.actuation, self.t, self.forces)


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

    def scenario_object(self) -> Scenario:
        """The scenario (with its stored parameters) that generated the data."""
        return scenario_class(self.scenario).from_dict(self.scenario_params)

    def body(self) -> Body:
        """The ground-truth body, rebuilt from ``body_params``."""
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
                    group.create_dataset(key, data=np.asarray(array, dtype=np.float64))
    return Path(path)


def read_dataset(path: str | os.PathLike[str]) -> Dataset:
    """Read and check an fhnn data set; raises :class:`DataFormatError` naming what is wrong."""
    path = Path(path)
    if not path.exists():
        raise DataFormatError(f"{path}: no such file")
    if path.is_dir():
        raise DataFormatError(f"{path}: is a folder, not a data file")
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
    if version is None or version != FORMAT_VERSION:
        raise DataFormatError(
            f"{path}: unsupported format_version {version!r} (this fhnn reads {FORMAT_VERSION})"
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
    try:
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
    if t.ndim != 1 or t.size < 2:
        raise DataFormatError(f"{path}: /{name}/t must have shape (T,) with T >= 2, got {t.shape}")
    states_shape = arrays["states"].shape
    if len(states_shape) != 3 or states_shape[0] < 1:
        raise DataFormatError(
            f"{path}: /{name}/states has shape {states_shape}, expected (N, {t.size}, 4) with N >= 1"
        )
    n = states_shape[0]
    expected = {
        "states": (n, t.size, 4),
        "states_clean": (n, t.size, 4),
        "derivs": (n, t.size, 4),
        "forces": (n, t.size, 2),
        "actuation": (n, 2, 3, 3),
    }
    for key, shape in expected.items():
        if arrays[key].shape != shape:
            raise DataFormatError(f"{path}: /{name}/{key} has shape {arrays[key].shape}, expected {shape}")
    for key, array in arrays.items():
        if not np.all(np.isfinite(array)):
            count = int(np.sum(~np.isfinite(array)))
            raise DataFormatError(f"{path}: /{name}/{key} has {count} NaN or infinite value(s)")
    if np.any(np.diff(t) <= 0):
        raise DataFormatError(f"{path}: /{name}/t is not strictly increasing")
    split = Split(**arrays)
    check_forcing(split, f"{path}: /{name}")
    return split


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
            f"{i} at t = {split.t[k]:g} s (recorded {split.forces[i, k].tolist()} N, actuation gives "
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
