"""A training run on disk: its configuration, building a model for a data set, training it,
checkpointing, resuming and loading.

Run folder layout::

    RUN/run.json        format "fhnn-run", format_version, package version, model kind and
                        configuration, training configuration, the data set (path relative to
                        RUN, SHA-256, scenario, seed), the data-derived build arguments, step
                        reached, best validation loss, loss history, why a guard stopped it
    RUN/model.eqx       weights at the step reached        (equinox.tree_serialise_leaves)
    RUN/best.eqx        weights with the best validation loss
    RUN/opt_state.eqx   optimiser state, for resuming

A checkpoint's files are replaced together (:func:`fhnn.files.commit_files`), so a run killed at
any point — even while writing — leaves either its previous checkpoint or the new one, whole, and a
full disk leaves the previous one; resuming continues from ``step`` with the same batches, giving
the same result as an uninterrupted run. The data set is recorded relative to the run folder, so a
run and its data moved together (a reproduction folder) still find each other, from any working
directory.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import numpy as np

from fhnn.config import Config, check_setting_names, deep_merge, frozen_config, nest
from fhnn.data.clock import dataset_clock
from fhnn.data.dataset import IMPORTED, Dataset, read_dataset
from fhnn.data.windows import Windows
from fhnn.errors import ConfigError, DataFormatError
from fhnn.files import check_new_folder, commit_files, recover_files
from fhnn.models.base import AbstractModel, AbstractVectorField
from fhnn.models.registry import MODELS
from fhnn.runtime import __version__
from fhnn.training.budget import Budget, pending_cut, ran_text, rewind_cut
from fhnn.training.plans import PLANS
from fhnn.training.trainer import TrainConfig, Trainer, TrainState

RUN_FORMAT = "fhnn-run"
#: Version of the run folder's layout; a run written by a newer fhnn (a higher version) is refused.
#: 2: FHNN's constants (input scales, radius range, body constants, ablation mask) are array leaves
#: of the checkpoints (1: static, not stored; read by :data:`FORMAT_1_CONSTANTS`).
RUN_FORMAT_VERSION = 2
#: Fields a format-1 checkpoint does not hold: static in format 1, so the model's own (built from
#: the stored build arguments) are kept; the body constants, plain floats in format 1, had no
#: optimiser state.
FORMAT_1_CONSTANTS = ("length_scale", "psi_scale", "time_scale", "r_scale", "sigma_scale", "r_range", "mask")
FORMAT_1_NO_OPT_STATE = (*FORMAT_1_CONSTANTS, "mass", "rho", "area", "volume")


@frozen_config
class RunConfig(Config):
    """Everything that decides a training run, besides its data: the model kind, the kind's
    configuration and the training configuration. Settings are addressed with dotted names —
    ``kind``, ``model.<field>`` (see the kind's configuration class) and ``train.<field>``
    (:class:`~fhnn.training.train_config.TrainConfig`).

    Attributes:
        kind: a model kind of :data:`~fhnn.models.registry.MODELS`.
        model: the kind's configuration (``None``: its defaults).
        train: the training configuration.
    """

    config_name = "run"

    kind: str = "fhnn"
    model: Config | None = None
    train: TrainConfig = TrainConfig()

    def __post_init__(self) -> None:
        kind = MODELS[self.kind]
        if self.model is None:
            object.__setattr__(self, "model", kind.default_config())
        super().__post_init__()

    def validate(self) -> None:
        expected = MODELS[self.kind].config
        if type(self.model) is not expected:
            raise ConfigError(
                f"run: model configuration for {self.kind!r} must be a {expected.__name__}, "
                f"got {type(self.model).__name__}"
            )

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> RunConfig:
        unknown = [k for k in values if k not in cls.field_names()]
        if unknown:
            check_setting_names(cls(), unknown)
        kind = str(values.get("kind", "fhnn"))
        model = values.get("model") or {}
        if not isinstance(model, Config):
            model = MODELS[kind].config.from_dict(model)
        train = values.get("train") or {}
        if not isinstance(train, TrainConfig):
            train = TrainConfig.from_dict(train)
        return cls(kind=kind, model=model, train=train)

    def with_settings(self, settings: Mapping[str, Any]) -> RunConfig:
        """A copy with dotted-name ``settings``; a new ``kind`` starts from its model defaults."""
        base = self
        if "kind" in settings and str(settings["kind"]) != self.kind:
            base = RunConfig(kind=str(settings["kind"]), train=self.train)
        rest = {k: v for k, v in settings.items() if k != "kind"}
        check_setting_names(base, rest)
        return RunConfig.from_dict(deep_merge(base.to_dict(), nest(rest)))


def checkpoint_interval() -> float:
    """``FHNN_CHECKPOINT_SECONDS`` (default 60): seconds between checkpoints between validations."""
    text = os.environ.get("FHNN_CHECKPOINT_SECONDS", "60")
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0:
        raise ConfigError(f"FHNN_CHECKPOINT_SECONDS must be a number of seconds >= 0, got {text!r}")
    return value


def file_sha256(path: str | os.PathLike[str]) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


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
    """A model, its trainer state and where they are saved.

    Attributes:
        folder: the run folder.
        config: what the run trains (:class:`RunConfig`).
        args: the data-derived build arguments (:attr:`ModelKind.arguments`).
        meta: the data set the run was trained on (``data``: its path relative to ``folder``,
            ``data_sha256``, ``scenario``, ``data_seed``; for imported data also ``clock``, the
            model's time against the table's: :meth:`clock`).
        state: the trainer's state (``None`` before training).
    """

    def __init__(
        self,
        folder: Path,
        config: RunConfig,
        args: dict[str, Any],
        meta: dict[str, Any],
        state: TrainState | None = None,
    ) -> None:
        self.folder, self.config, self.args, self.meta, self.state = folder, config, args, meta, state
        #: The step of the last checkpoint written (``None``: none yet).
        self.saved_step: int | None = state.step if state is not None else None
        #: Seconds between checkpoints written between validations (a kill loses at most this much
        #: work); environment variable ``FHNN_CHECKPOINT_SECONDS``, default 60.
        self.checkpoint_seconds = checkpoint_interval()

    @property
    def kind(self) -> str:
        return self.config.kind

    @property
    def model_config(self) -> Config:
        return self.config.model  # type: ignore[return-value]

    @property
    def train_config(self) -> TrainConfig:
        return self.config.train

    @property
    def finished(self) -> bool:
        """Whether every phase of the training configuration has run."""
        if self.state is None:
            return False
        if MODELS[self.kind].fit is not None:
            return self.state.step >= 1
        cfg = self.train_config
        done = self.state.step >= cfg.steps + cfg.lbfgs_steps + cfg.track_steps
        return done and pending_cut(self.state) is None

    def ran(self) -> str:
        """What the training ran so far (:func:`~fhnn.training.budget.ran_text`), or "one fit"."""
        if MODELS[self.kind].fit is not None:
            return "one fit"
        return ran_text(self.state.history if self.state else [], self.train_config)

    def continue_cut(self) -> str | None:
        """Where a time budget cut a phase of this run: set the run back there, so that training
        continues (:func:`~fhnn.training.budget.rewind_cut`); returns what continues, or ``None``."""
        if self.state is None or MODELS[self.kind].fit is not None:
            return None
        return rewind_cut(self.state, self.train_config)

    def extend(self, config: RunConfig) -> None:
        """Continue this run under ``config``, which may differ from the stored one only by more
        Adam steps (``train.steps``), and only while no L-BFGS polish has run. The learning-rate
        schedule is recomputed for the new total, so the result differs from a run started with
        that many steps."""
        changed = self.config.differences(config)
        if changed != ["train.steps"] or config.train.steps <= self.train_config.steps:
            raise ConfigError(
                f"--extend continues {self.folder} with more Adam steps only: give --steps larger than "
                f"its {self.train_config.steps}"
                + (
                    f" and no other change ({', '.join(c for c in changed if c != 'train.steps')})"
                    if changed
                    else ""
                )
            )
        cfg = self.train_config
        if (cfg.lbfgs_steps or cfg.track_steps) and self.state is not None and self.state.step > cfg.steps:
            raise ConfigError(
                f"{self.folder} has gone past its Adam phase (into the L-BFGS polish or the whole-track "
                "fit); it cannot be extended with Adam"
            )
        self.config = config

    @property
    def best_model(self) -> AbstractModel:
        """The model with the best validation loss so far."""
        if self.state is None:
            raise ConfigError(f"{self.folder}: the run has not been trained yet")
        return self.state.best_model

    @classmethod
    def create(
        cls,
        folder: str | os.PathLike[str],
        dataset: Dataset,
        config: RunConfig | None = None,
        *,
        data_path: str | os.PathLike[str] | None = None,
        data_ref: str | None = None,
    ) -> Run:
        """A new run of ``config`` on ``dataset``.

        Args:
            folder: the run folder (its parent must exist).
            dataset: the data set to train on.
            config: what to train (default: FHNN with the default training).
            data_path: the file ``dataset`` was read from; recorded relative to ``folder`` with its
                SHA-256, so that ``evaluate`` and ``inspect`` find it (``None``: a data set in
                memory; they then need it passed explicitly).
            data_ref: record this path (relative to ``folder``) instead of ``data_path``'s, for a
                run folder that will be moved beside its data (a reproduction job).
        """
        folder = Path(folder)
        check_new_folder(folder)
        config = config or RunConfig()
        check_trainable(dataset)
        meta: dict[str, Any] = {"data": None}
        if data_path is not None:
            meta["data"] = data_ref or os.path.relpath(Path(data_path).resolve(), folder.resolve())
            meta["data_sha256"] = file_sha256(data_path)
        meta.update(scenario=dataset.scenario, data_seed=dataset.seed)
        if "import" in dataset.extra:
            meta["clock"] = dataset_clock(dataset)
        return cls(folder, config, MODELS[config.kind].arguments(dataset), meta)

    def clock(self) -> dict[str, Any]:
        """How the model's time relates to the times of the table its data were imported from:
        ``{"origin": the date-time the table's seconds count from (None: the table gave
        seconds), "offset": seconds of that clock at the model's t = 0}``. A run on simulated
        data: origin None, offset 0. A run on imported data made before runs recorded it reads
        it from its data file, or, where that is gone, takes origin None and offset 0 and says
        why under ``"unknown"`` (the caller tells the user: times are then the model's own)."""
        if "clock" in self.meta:
            return dict(self.meta["clock"])
        if self.meta.get("scenario") == IMPORTED and self.meta.get("data"):
            try:
                return dataset_clock(self.dataset())
            except (DataFormatError, OSError) as exc:
                unknown = f"the run predates recorded clocks and its data set is unreadable ({exc})"
                return {"origin": None, "offset": 0.0, "unknown": unknown}
        return {"origin": None, "offset": 0.0}

    def skeleton(self) -> AbstractModel:
        """A fresh model of this run's kind, configuration, build arguments and seed."""
        return MODELS[self.kind].make(self.model_config, self.args, self.train_config.seed)

    def outline(self) -> AbstractModel:
        """:meth:`skeleton`'s structure with ``jax.ShapeDtypeStruct`` for its arrays: what loading
        a checkpoint and sizing windows need, without drawing (and compiling the draws of) the
        initial weights."""
        return eqx.filter_eval_shape(
            MODELS[self.kind].make, self.model_config, self.args, self.train_config.seed
        )

    def data_file(self) -> Path:
        """The data set the run was trained on, checked against its recorded SHA-256."""
        ref = self.meta.get("data")
        if not ref:
            raise DataFormatError(f"{self.folder}: the run records no data file; pass the data set")
        path = self.folder / ref
        if not path.is_file() and Path(ref).is_file():  # runs written before paths were relative
            path = Path(ref)
        if not path.is_file():
            raise DataFormatError(
                f"{self.folder}: its data set {ref!r} is not where the run recorded it; pass the data set"
            )
        want = self.meta.get("data_sha256")
        if want and file_sha256(path) != want:
            raise DataFormatError(
                f"{path}: the data set changed since the run {self.folder} was trained on it "
                "(SHA-256 differs); pass the data set to use explicitly"
            )
        return path

    def dataset(self) -> Dataset:
        """The data set the run was trained on (see :meth:`data_file`)."""
        return read_dataset(self.data_file())

    def trainer(
        self,
        dataset: Dataset,
        on_step: Callable[[str, int], None] | None = None,
        budget: Budget | None = None,
    ) -> Trainer:
        """The :class:`~fhnn.training.trainer.Trainer` of this run on ``dataset`` (its training
        windows sized for the model); ``on_step(phase, step)`` is told of every quasi-Newton step and
        every chunk of Adam steps; ``budget``: the command's time budget (default:
        ``train.max_time`` from now)."""
        return Trainer(
            self.train_config,
            dataset.train,
            dataset.val,
            window=self.check_windows(dataset),
            on_step=on_step,
            budget=budget,
        )

    def check_windows(self, dataset: Dataset) -> int:
        """The training window (samples per example: the model's, or the multi-step loss's
        ``train.shoot`` for a vector field) after checking that ``dataset``'s train and val splits
        hold such windows (:meth:`~fhnn.data.windows.Windows.check`; a
        :class:`~fhnn.errors.ConfigError` otherwise, saying how to shorten the multi-step loss's)."""
        skeleton = self.outline()
        window = skeleton.window
        if isinstance(skeleton, AbstractVectorField):  # a vector field takes the multi-step loss
            window = max(window, self.train_config.shoot)
        try:
            for split in (dataset.train, dataset.val):
                Windows.check(split, window, skip=self.train_config.first_start)
        except ConfigError as err:
            shoot = self.train_config.shoot
            if window != shoot:
                raise
            raise ConfigError(
                f"{err} (the multi-step loss's windows, train.shoot={shoot}: give longer trajectories "
                f"or fewer samples per window, --set train.shoot=N with N < {shoot}; 0 turns the loss off)"
            ) from None
        return window

    def windowless(self, dataset: Dataset) -> tuple[int, dict[str, tuple[int, int]]]:
        """:meth:`check_windows`'s window and ``{split: (trajectories without such a window,
        trajectories)}`` for ``dataset``'s train and val splits: those shorter than the window
        (from sample ``train.first_start``) add nothing to the loss on windows, nor to its
        validation."""
        window = self.check_windows(dataset)
        return window, {
            name: (Windows.without_window(split, window, skip=self.train_config.first_start), split.n_traj)
            for name, split in (("train", dataset.train), ("val", dataset.val))
        }

    def train(
        self,
        dataset: Dataset,
        *,
        until: int | None = None,
        callback: Callable[[TrainState, dict[str, float]], None] | None = None,
        save: bool = True,
        on_step: Callable[[str, int], None] | None = None,
        budget: Budget | None = None,
    ) -> TrainState:
        """Train (or fit) up to ``until`` Adam steps (default: to the end of every phase),
        checkpointing at every validation when ``save``; ``callback(state, record)`` at each,
        ``on_step(phase, step)`` between them (:class:`~fhnn.training.trainer.Trainer`), under
        ``budget`` (default: ``train.max_time`` from now)."""
        trainer = self.trainer(dataset, on_step, budget)
        if MODELS[self.kind].fit is not None:  # a one-shot fit (a regression), not gradient descent
            return self._fit(trainer, dataset, save)
        self.begin(trainer, callback=callback, save=save)
        self.adam(trainer, until=until, callback=callback, save=save)
        return self.finish(trainer, until=until, callback=callback, save=save)

    def begin(
        self,
        trainer: Trainer,
        *,
        callback: Callable[[TrainState, dict[str, float]], None] | None = None,
        save: bool = True,
    ) -> None:
        """The run's first phase: a new state, and the warm-up (if the plan has one and it has not
        run yet), checkpointed when ``save``."""
        if self.state is None:
            self.state = trainer.init(self.skeleton())
        if self.state.step == 0 and not any(r.get("phase") == "warmup" for r in self.state.history):
            self.state = trainer.warmup(self.state, callback=callback)
            if save and self.state.history:
                self.save()

    def adam(
        self,
        trainer: Trainer,
        *,
        until: int | None = None,
        callback: Callable[[TrainState, dict[str, float]], None] | None = None,
        save: bool = True,
    ) -> None:
        """The Adam phase up to ``until`` (default: its end), checkpointed at every record and
        every :attr:`checkpoint_seconds` when ``save``."""
        self.state = trainer.run(
            self.state,  # type: ignore[arg-type]
            until=until,
            callback=self.saving(callback, save),
            checkpoint=(lambda state: self.save()) if save else None,
            checkpoint_seconds=self.checkpoint_seconds,
        )

    def saving(
        self, callback: Callable[[TrainState, dict[str, float]], None] | None, save: bool
    ) -> Callable[[TrainState, dict[str, float]], None]:
        """The Adam phase's record callback: checkpoint (when ``save``), then ``callback``."""

        def on_validation(state: TrainState, record: dict[str, float]) -> None:
            if save:
                self.save()
            if callback is not None:
                callback(state, record)

        return on_validation

    def finish(
        self,
        trainer: Trainer,
        *,
        until: int | None = None,
        callback: Callable[[TrainState, dict[str, float]], None] | None = None,
        save: bool = True,
    ) -> TrainState:
        """After the Adam phase: its checkpoint, and the polish (when the plan has one, Adam is
        over and ``until`` reaches past it)."""
        assert self.state is not None
        if save:
            self.save()
        cfg = self.train_config
        polish = cfg.lbfgs_steps > 0 and cfg.steps <= self.state.step < cfg.steps + cfg.lbfgs_steps
        if polish and (until is None or until > self.train_config.steps):
            # the Adam-end checkpoint above is what an interrupted polish restarts from
            self.state = trainer.polish(self.state, callback=callback)
            if save:
                self.save(polished=True)
        polished = self.state.step >= cfg.steps + cfg.lbfgs_steps
        if cfg.track_steps > 0 and polished and not self.finished:
            if until is None or until > cfg.steps + cfg.lbfgs_steps:
                self.state = trainer.track_fit(self.state, callback=self.saving(callback, save))
                if save:
                    self.save(polished=True)
        return self.state

    def _fit(self, trainer: Trainer, dataset: Dataset, save: bool) -> TrainState:
        fit = MODELS[self.kind].fit
        assert fit is not None
        model, extra = fit(self.model_config, dataset)
        val = trainer.validate(model)
        record = {"step": 1, **{f"val_{k}": v for k, v in val.items()}, **extra}
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
        if self.state is None:
            raise ConfigError(f"{self.folder}: nothing to save before training")
        self.folder.mkdir(exist_ok=True)
        info = {
            "format": RUN_FORMAT,
            "format_version": RUN_FORMAT_VERSION,
            "version": __version__,
            "model": self.kind,
            "model_config": self.model_config.to_dict(),
            "train_config": self.train_config.to_dict(),
            "build_arguments": self.args,
            "step": self.state.step,
            "skipped_since_record": self.state.skipped,
            "stopped": self.state.stopped,
            "best_val": self.state.best_val,
            "history": self.state.history,
            **self.meta,
        }
        state = self.state
        writers: dict[str, Callable[[Path], None]] = {
            "model.eqx": lambda tmp: eqx.tree_serialise_leaves(tmp, state.model),
            "best.eqx": lambda tmp: eqx.tree_serialise_leaves(tmp, state.best_model),
        }
        if not polished:
            writers["opt_state.eqx"] = lambda tmp: eqx.tree_serialise_leaves(tmp, state.opt_state)
        writers["run.json"] = lambda tmp: tmp.write_text(json.dumps(info, indent=1), encoding="utf-8")
        commit_files(self.folder, writers)  # all files of a checkpoint change together, or none
        self.saved_step = self.state.step

    @classmethod
    def load(cls, folder: str | os.PathLike[str], *, expect_model: str | None = None) -> Run:
        """The run saved in ``folder`` (of kind ``expect_model`` when given), at its last checkpoint."""
        folder = Path(folder)
        recover_files(folder)  # a checkpoint write a kill interrupted: completed or undone
        info_path = folder / "run.json"
        if not info_path.is_file():
            raise DataFormatError(f"{folder}: not an fhnn run (no run.json)")
        try:
            info = json.loads(info_path.read_text())
        except json.JSONDecodeError as exc:
            raise DataFormatError(f"{info_path}: not valid JSON ({exc})") from None
        if info.get("format") != RUN_FORMAT:
            raise DataFormatError(f"{info_path}: not an fhnn run (format {info.get('format')!r})")
        version = info.get("format_version", 1)  # runs written before the field existed are version 1
        if not isinstance(version, int) or not 1 <= version <= RUN_FORMAT_VERSION:
            raise DataFormatError(
                f"{info_path}: unsupported run format_version {version!r} (this fhnn {__version__} reads "
                f"1 to {RUN_FORMAT_VERSION}; a newer fhnn wrote it)"
            )
        kind = info.get("model")
        if kind not in MODELS:
            raise DataFormatError(f"{info_path}: unknown model {kind!r}")
        if expect_model is not None and kind != expect_model:
            raise DataFormatError(f"{folder}: checkpoint is a {kind!r} model, not {expect_model!r}")
        try:
            # a field a run predates takes the value that meant "off" when it was stored: the
            # paper's settings, which were the configuration defaults then (plans.PAPER_*)
            former = PLANS["adam"]
            model_config = {
                **MODELS[kind].stored_defaults,
                **former.model_settings(kind),
                **info["model_config"],
            }
            train_config = {**former.train.to_dict(), **info["train_config"]}
            config = RunConfig.from_dict({"kind": kind, "model": model_config, "train": train_config})
        except (ConfigError, KeyError, TypeError) as exc:
            raise DataFormatError(f"{info_path}: unreadable configuration ({exc})") from None
        meta = {k: info[k] for k in ("data", "data_sha256", "scenario", "data_seed", "clock") if k in info}
        run = cls(folder, config, info["build_arguments"], meta)
        old = version == 1  # a format-1 file lacks constants: they come from a real skeleton
        skeleton = run.skeleton() if old else run.outline()
        model = _load_leaves(folder / "model.eqx", skeleton, FORMAT_1_CONSTANTS if old else ())
        best = _load_leaves(folder / "best.eqx", skeleton, FORMAT_1_CONSTANTS if old else ())
        opt_state = None
        if MODELS[kind].fit is None:
            init = Trainer.optimizer_for(config.train).init  # format 1 keeps a fresh state's arrays
            params = eqx.filter(skeleton, _array_or_shape)
            like = init(params) if old else eqx.filter_eval_shape(init, params)
            opt_state = _load_leaves(folder / "opt_state.eqx", like, FORMAT_1_NO_OPT_STATE if old else ())
        run.state = TrainState(
            model=model,
            opt_state=opt_state,
            step=int(info["step"]),
            best_model=best,
            best_val=float(info["best_val"]),
            history=list(info.get("history", [])),
            skipped=float(info.get("skipped_since_record", 0.0)),
            stopped=info.get("stopped"),
        )
        return run


def _load_leaves(path: Path, like: Any, absent: tuple[str, ...] = ()) -> Any:
    """The arrays of ``path`` in the structure of ``like``, except leaves under a field named in
    ``absent`` (not in the file: ``like``'s are kept); a missing, truncated or foreign file is a
    :class:`DataFormatError` naming it."""
    if not path.is_file():
        raise DataFormatError(f"{path}: checkpoint files missing or incompatible (no such file)")

    def spec(key_path: tuple[Any, ...], _: Any) -> Callable[[Any, Any], Any]:
        names = {getattr(k, "name", None) for k in key_path}
        return _keep if names & set(absent) else eqx.default_deserialise_filter_spec

    try:
        return eqx.tree_deserialise_leaves(
            path, like, filter_spec=jax.tree_util.tree_map_with_path(spec, like)
        )
    except (OSError, ValueError, RuntimeError, EOFError) as exc:
        kind = "truncated or corrupt" if isinstance(exc, OSError | EOFError | ValueError) else "incompatible"
        raise DataFormatError(
            f"{path}: checkpoint files missing or incompatible ({kind}: it does not hold this run's "
            "model; retrain, or restore the file)"
        ) from None


def _array_or_shape(leaf: Any) -> bool:
    """An array of a model or of its :meth:`Run.outline` (``eqx.is_array`` for either)."""
    return eqx.is_array(leaf) or isinstance(leaf, jax.ShapeDtypeStruct)


def _keep(_file: Any, like: Any) -> Any:
    return like


def load_run(folder: str | os.PathLike[str]) -> Run:
    """The run saved in ``folder``; ``run.best_model`` is its best model, ``run.dataset()`` its data."""
    return Run.load(folder)
