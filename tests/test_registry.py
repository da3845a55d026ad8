"""The model registry's contract: every registered kind goes through build → two training steps
→ save → load → rollout → metrics, and every place that lists models reads the registry."""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import numpy as np
import pytest

from fhnn.errors import ConfigError
from fhnn.evaluation.evaluate import evaluate
from fhnn.experiments.grid import ReproduceConfig
from fhnn.experiments.tables import MODEL_NAMES
from fhnn.models.base import AbstractModel, Rollout
from fhnn.models.registry import MODELS
from fhnn.training.run import Run, RunConfig

from .conftest import paper_train, small_dataset


@pytest.fixture(scope="module")
def data():
    return small_dataset("steady_vortex", n_traj=6, duration=2.0, test_duration=3.0)


def _small(kind: str):
    config_class = MODELS[kind].config
    fields = {f.name for f in dataclasses.fields(config_class)}
    small = {"width": 8, "depth": 1, "slow_weight": 0.0}  # FHNN's windows unweighted, as in the paper
    return config_class.from_dict({k: v for k, v in small.items() if k in fields})


@pytest.mark.parametrize("kind", list(MODELS))
def test_every_registered_model_trains_saves_loads_rolls_out_and_scores(kind, data, tmp_path):
    entry = MODELS[kind]
    config = RunConfig(kind=kind, model=_small(kind), train=paper_train(steps=2, val_every=1, batch_size=16))
    run = Run.create(tmp_path / "run", data, config)
    assert isinstance(run.skeleton(), AbstractModel)
    state = run.train(data)
    assert state.step == (1 if entry.fit is not None else 2)
    assert np.isfinite(state.best_val)
    assert {"run.json", "model.eqx", "best.eqx"} <= {p.name for p in (tmp_path / "run").iterdir()}

    loaded = Run.load(tmp_path / "run", expect_model=kind)
    assert loaded.config == config and loaded.state.step == state.step
    for a, b in zip(
        jax.tree_util.tree_leaves(eqx.filter(state.best_model, eqx.is_array)),
        jax.tree_util.tree_leaves(eqx.filter(loaded.best_model, eqx.is_array)),
        strict=True,
    ):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))

    ro = loaded.best_model.rollout(data.test, 2.0)
    assert isinstance(ro, Rollout)
    assert ro.states.shape == (data.test.n_traj, ro.t.size, 4) and ro.t[-1] == pytest.approx(2.0)
    again = state.best_model.rollout(data.test, 2.0)
    np.testing.assert_array_equal(ro.states, again.states)  # the checkpoint is the model

    result = evaluate(loaded.best_model, data, [1, 2])
    for h in ("1", "2"):
        m = result["horizons"][h]
        assert m["n_traj"] == data.test.n_traj
        assert np.isfinite(m["rmse_pos"]) or m["diverged"] > 0
    assert len(result["diverged"]) == data.test.n_traj


def test_every_place_that_lists_models_reads_the_registry():
    from typer.main import get_command

    from fhnn.cli.app import app

    assert list(ReproduceConfig().models) == list(MODELS)
    assert list(ReproduceConfig.quick().models) == [k for k, e in MODELS.items() if e.in_paper]
    assert {k: MODEL_NAMES[k] for k in MODELS} == {k: e.label for k, e in MODELS.items()}
    assert set(MODELS["fhnn"].variants) <= set(MODEL_NAMES)
    train = get_command(app).commands["train"]
    help_text = next(p.help for p in train.params if p.name == "model")
    assert all(kind in help_text for kind in MODELS)


def test_unknown_model_kind_is_refused_with_a_suggestion():
    with pytest.raises(
        ConfigError, match=r"unknown model 'hnnn' \(did you mean 'hnn'\?\); available: fhnn, "
    ):
        MODELS["hnnn"]
    with pytest.raises(ConfigError, match="unknown model 'gpt'"):
        RunConfig(kind="gpt")
    with pytest.raises(ConfigError, match="model configuration for 'hnn' must be a MLPConfig"):
        RunConfig(kind="hnn", model=MODELS["fhnn"].config())
