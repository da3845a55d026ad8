"""A training run on disk: build a model for a data set, train it, checkpoint, resume, load.

Run folder layout::

    RUN/run.json        format "fhnn-run", package version, model kind and configuration,
                        training configuration, data set path and scenario, the data-derived
                        build arguments, step reached, best validation loss, loss history
    RUN/model.eqx       weights at the step reached        (equinox.tree_serialise_leaves)
    RUN/best.eqx        weights with the best validation loss
    RUN/opt_state.eqx   optimiser state, for resuming

Everything is written to temporary files and renamed, so a killed run leaves the previous
checkpoint intact; resuming continues from ``step`` with the same batches, giving the same result
as an uninterrupted run.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import numpy as np

from fhnn import __version__
from fhnn.config import Config
from fhnn.data.dataset import Dataset, atomic_output, write_atomic
from fhnn.errors import ConfigError, DataFormatError
from fhnn.models.base import AbstractVectorField
from fhnn.models.baselines import MLPConfig, build_baseline
from fhnn.models.dhn import DHNConfig, build_dhn
from fhnn.models.fhnn import FHNNConfig, build_fhnn
from fhnn.models.sindy import SINDyConfig, empty_sindy, fit_sindy
from fhnn.training.trainer import TrainConfig, Trainer, TrainState

RUN_FORMAT = "fhnn-run"
#: Model kinds trainable by gradient descent, with their configuration classes.
MODELS: dict[str, type[Config]] = {
    "fhnn": FHNNConfig,
    "node": MLPConfig,
    "hnn": MLPConfig,
    "lnn": MLPConfig,
    "dhnn": MLPConfig,
    "sindy": SINDyConfig,
    "dhn": DHNConfig,
}


def build_arguments(dataset: Dataset, kind: str = "fhnn") -> dict[str, Any]:
    """Data-derived arguments of a model's builder: for FHNN the body constants and input
    scales, for the baselines the training data's statistics."""
    train = dataset.train
    if kind != "fhnn":
        states = train.states.reshape(-1, 4)
        std = states.std(axis=0)
        return {
            "n_traj": train.n_traj,
            "step_std": np.diff(train.states, axis=1).reshape(-1, 4).std(axis=0).tolist(),
            "state_mean": states.mean(axis=0).tolist(),
            "state_std": std.tolist(),
            "force_std": float(max(train.forces.std(), 1e-3)),
            "deriv_std": train.derivs.reshape(-1, 4).std(axis=0).tolist(),
            "energy": float(np.mean(std[2:] ** 2)),
        }
    body = dataset.body()
    pos = train.states[..., :2]
    radius = np.hypot(pos[..., 0], pos[..., 1])
    return {
        "mass": body.mass,
        "rho": body.rho,
        "area": body.area,
        "volume": body.volume,
        "time_dependent": bool(dataset.scenario_object().time_dependent),
        "fluid_inertia": bool(body.fluid_inertia),
        "length_scale": float(np.sqrt(np.mean(np.sum(pos**2, axis=-1)))),
        "speed_scale": float(np.sqrt(np.mean(train.states[..., 2:] ** 2))),
        "time_scale": float(train.t[-1]),
        "r_range": [float(radius.min()), float(radius.max())],
    }


def build_model(kind: str, config: Any, args: dict[str, Any], seed: int) -> AbstractVectorField:
    """A fresh model ``kind`` from its configuration, data-derived arguments and seed."""
    if kind not in MODELS:
        raise ConfigError(f"unknown model {kind!r}; available: {', '.join(MODELS)}")
    key = jax.random.PRNGKey(seed)
    if kind == "fhnn":
        return build_fhnn(config, **args, key=key)
    if kind == "sindy":
        return empty_sindy(config)
    if kind == "dhn":
        return build_dhn(config, args, args["n_traj"], key)
    return build_baseline(kind, config, args, key)


def check_trainable(dataset: Dataset) -> None:
    """Raise :class:`DataFormatError` if the data set cannot be trained on."""
    for name in ("train", "val"):
        split = dataset[name]
        if split.n_times < 2:
            raise DataFormatError(f"split {name!r} needs at least two samples per trajectory")
        for key in ("states", "derivs"):
            if not np.all(np.isfinite(getattr(split, key))):
                raise DataFormatError(f"split {name!r}: {key} contains NaN or infinite values")


class Run:
    """A model, its trainer state and where they are saved."""

    def __init__(
        self,
        folder: Path,
        kind: str,
        model_config: Any,
        train_config: TrainConfig,
        args: dict[str, Any],
        meta: dict[str, Any],
        state: TrainState | None = None,
    ) -> None:
        self.folder, self.kind, self.model_config, self.train_config = (
            folder,
            kind,
            model_config,
            train_config,
        )
        self.args, self.meta, self.state = args, meta, state

    @classmethod
    def create(
        cls,
        folder: str | os.PathLike[str],
        dataset: Dataset,
        data_path: str,
        kind: str,
        model_config: Any,
        train_config: TrainConfig,
    ) -> Run:
        folder = Path(folder)
        if not folder.parent.is_dir():
            raise ConfigError(f"output folder '{folder.parent}' does not exist")
        check_trainable(dataset)
        meta = {"data": str(data_path), "scenario": dataset.scenario, "data_seed": dataset.seed}
        return cls(folder, kind, model_config, train_config, build_arguments(dataset, kind), meta)

    def skeleton(self) -> AbstractVectorField:
        return build_model(self.kind, self.model_config, self.args, self.train_config.seed)

    def train(
        self,
        dataset: Dataset,
        *,
        until: int | None = None,
        callback: Callable[[TrainState, dict[str, float]], None] | None = None,
        save: bool = True,
    ) -> TrainState:
        window = 2 if self.kind == "sindy" else self.skeleton().window
        trainer = Trainer(self.train_config, dataset.train, dataset.val, window=window)
        if self.kind == "sindy":  # a regression, not gradient descent: fitted in one go
            return self._fit_sindy(trainer, dataset, save)
        if self.state is None:
            self.state = trainer.init(self.skeleton())
        if self.state.step == 0 and not any(r.get("phase") == "warmup" for r in self.state.history):
            self.state = trainer.warmup(self.state, callback=callback)
            if save and self.state.history:
                self.save()

        def on_validation(state: TrainState, record: dict[str, float]) -> None:
            if save:
                self.save()
            if callback is not None:
                callback(state, record)

        self.state = trainer.run(self.state, until=until, callback=on_validation)
        if save:
            self.save()
        polish = self.train_config.lbfgs_steps > 0 and self.state.step == self.train_config.steps
        if polish and (until is None or until > self.train_config.steps):
            # the Adam-end checkpoint above is what an interrupted polish restarts from
            self.state = trainer.polish(self.state, callback=callback)
            if save:
                self.save(polished=True)
        return self.state

    def _fit_sindy(self, trainer: Trainer, dataset: Dataset, save: bool) -> TrainState:
        model, equations = fit_sindy(self.model_config, dataset.train)
        val = trainer.validate(model)
        record = {"step": 1, **{f"val_{k}": v for k, v in val.items()}, "equations": equations}
        self.state = TrainState(
            model=model,
            opt_state=None,
            step=1,
            best_model=model,
            best_val=val["deriv"] + val["step"],
            history=[record],
        )
        if save:
            self.save()
        return self.state

    def save(self, *, polished: bool = False) -> None:
        """Write the checkpoint. During and after the L-BFGS phase only the model files change:
        ``opt_state.eqx`` keeps the Adam state, and ``step`` in run.json says how far the run got."""
        assert self.state is not None
        self.folder.mkdir(exist_ok=True)
        info = {
            "format": RUN_FORMAT,
            "version": __version__,
            "model": self.kind,
            "model_config": self.model_config.to_dict(),
            "train_config": self.train_config.to_dict(),
            "build_arguments": self.args,
            "step": self.state.step,
            "best_val": self.state.best_val,
            "history": self.state.history,
            **self.meta,
        }
        _save_leaves(self.folder / "model.eqx", self.state.model)
        _save_leaves(self.folder / "best.eqx", self.state.best_model)
        if not polished:
            _save_leaves(self.folder / "opt_state.eqx", self.state.opt_state)
        write_atomic(self.folder / "run.json", json.dumps(info, indent=1))

    @classmethod
    def load(cls, folder: str | os.PathLike[str], *, expect_model: str | None = None) -> Run:
        folder = Path(folder)
        info_path = folder / "run.json"
        if not info_path.is_file():
            raise DataFormatError(f"{folder}: not an fhnn run (no run.json)")
        try:
            info = json.loads(info_path.read_text())
        except json.JSONDecodeError as exc:
            raise DataFormatError(f"{info_path}: not valid JSON ({exc})") from None
        if info.get("format") != RUN_FORMAT:
            raise DataFormatError(f"{info_path}: not an fhnn run (format {info.get('format')!r})")
        kind = info.get("model")
        if kind not in MODELS:
            raise DataFormatError(f"{info_path}: unknown model {kind!r}")
        if expect_model is not None and kind != expect_model:
            raise DataFormatError(f"{folder}: checkpoint is a {kind!r} model, not {expect_model!r}")
        model_config = MODELS[kind].from_dict(info["model_config"])
        train_config = TrainConfig.from_dict(info["train_config"])
        meta = {k: info[k] for k in ("data", "scenario", "data_seed") if k in info}
        run = cls(folder, kind, model_config, train_config, info["build_arguments"], meta)
        skeleton = run.skeleton()
        try:
            model = eqx.tree_deserialise_leaves(folder / "model.eqx", skeleton)
            best = eqx.tree_deserialise_leaves(folder / "best.eqx", skeleton)
            opt_state = None
            if kind != "sindy":
                like = Trainer.optimizer_for(train_config).init(eqx.filter(skeleton, eqx.is_array))
                opt_state = eqx.tree_deserialise_leaves(folder / "opt_state.eqx", like)
        except (OSError, ValueError, RuntimeError) as exc:
            raise DataFormatError(f"{folder}: checkpoint files missing or incompatible ({exc})") from None
        run.state = TrainState(
            model=model,
            opt_state=opt_state,
            step=int(info["step"]),
            best_model=best,
            best_val=float(info["best_val"]),
            history=list(info.get("history", [])),
        )
        return run


def _save_leaves(path: Path, tree: Any) -> None:
    with atomic_output(path) as tmp:
        eqx.tree_serialise_leaves(tmp, tree)
