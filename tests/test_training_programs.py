"""The trainer's compiled programs: traced once per shape and configuration, the penalty-free Adam
step, the warm-up part without the stream MLP, and the commands' compilation cache folder."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import fhnn.training.trainer as trainer_module
from fhnn.models.fhnn import FHNNConfig
from fhnn.models.registry import MODELS
from fhnn.runtime import CACHE_ENV, default_cache_dir
from fhnn.training.trainer import ADAM_FIELDS, PENALTY_FREE_MIN_STEPS, TrainConfig, Trainer, adam_step

from .conftest import small_dataset


def arrays(tree):
    return jax.tree_util.tree_leaves(eqx.filter(tree, eqx.is_array))


@pytest.fixture(scope="module")
def data():
    return small_dataset("steady_vortex", n_traj=6, duration=2.0)


def fresh(data, seed=0, **model):
    return MODELS["fhnn"].make(FHNNConfig(width=8, depth=2, **model), MODELS["fhnn"].arguments(data), seed)


def test_a_second_trainer_of_the_same_shapes_traces_nothing(data, monkeypatch):
    """The Adam step, the validation and the quasi-Newton iteration read data, scales and keys as
    arguments and only the fields they use as static configuration: a second run with another seed
    and validation interval reuses all three programs (no Python trace of the loss at all)."""
    traces = []
    original = trainer_module.loss_terms

    def counting(model, batch, scales):
        traces.append(1)
        return original(model, batch, scales)

    monkeypatch.setattr(trainer_module, "loss_terms", counting)

    def train(seed, val_every):
        config = TrainConfig(
            steps=4, val_every=val_every, batch_size=16, lbfgs_steps=2, lbfgs_pairs=64, seed=seed
        )
        tr = Trainer(config, data.train, data.val)
        state = tr.run(tr.init(fresh(data, seed)))
        tr.polish(state)
        return len(traces)

    first = train(0, 2)
    assert first > 0
    assert train(7, 4) == first  # nothing traced again
    assert TrainConfig(seed=1, val_every=3).only(ADAM_FIELDS) == TrainConfig().only(ADAM_FIELDS)


def test_the_penalty_free_step_is_the_same_step_once_the_weight_is_zero(data):
    config = TrainConfig(steps=4 * PENALTY_FREE_MIN_STEPS, batch_size=32)
    end = int(config.flow_anneal * config.steps)
    assert config.regularizes(end - 1) and not config.regularizes(end)
    # a short run keeps one program: too few steps to gain a second compilation back
    short = TrainConfig(steps=PENALTY_FREE_MIN_STEPS)
    assert all(short.regularizes(i) for i in (0, short.steps // 2, short.steps - 1))
    assert not TrainConfig(lambda_flow=0.0).regularizes(0)
    tr = Trainer(config, data.train, data.val)
    state = tr.init(fresh(data, far_field="none"))  # the whole ψ is penalised: non-zero from the start
    args = (state.model, state.opt_state, jnp.asarray(end + 3), tr._train, tr.scales, tr._key)
    with_penalty = adam_step(*args, config.only(ADAM_FIELDS), True)
    without = adam_step(*args, config.only(ADAM_FIELDS), False)
    assert "flow" in with_penalty[2] and "flow" not in without[2]
    for a, b in zip(arrays(with_penalty[:2]), arrays(without[:2]), strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-13, atol=1e-15)
    # before the end of the anneal the penalty is in the loss
    early = (state.model, state.opt_state, jnp.asarray(0), tr._train, tr.scales, tr._key)
    terms = adam_step(*early, config.only(ADAM_FIELDS), True)[2]
    data_only = adam_step(*early, config.only(ADAM_FIELDS), False)[2]["loss"]
    assert float(terms["loss"] - data_only) == pytest.approx(
        config.lambda_flow * float(terms["flow"]), rel=1e-9
    )
    assert float(terms["flow"]) > 0


def test_warmup_part_has_no_stream_mlp_and_predicts_what_the_model_predicts(data):
    model = fresh(data)
    part, restore = model.warmup()
    assert part.flow.mlp is None
    n_model = sum(x.size for x in jax.tree_util.tree_leaves(eqx.filter(model, eqx.is_array)))
    n_part = sum(x.size for x in jax.tree_util.tree_leaves(eqx.filter(part, eqx.is_array)))
    n_mlp = sum(x.size for x in jax.tree_util.tree_leaves(eqx.filter(model.flow.mlp, eqx.is_array)))
    assert n_part == n_model - n_mlp
    rng = np.random.default_rng(3)
    for _ in range(5):
        s = jnp.asarray(rng.normal(size=4))
        f = jnp.asarray(rng.normal(size=2))
        np.testing.assert_array_equal(np.asarray(part(s, 0.3, f)), np.asarray(model(s, 0.3, f)))
    # a fitted part goes back with the original MLP and the fitted linear flow
    fitted = eqx.tree_at(lambda m: m.eom.flow.quadratic, part, jnp.asarray([0.1, 0.2, 0.3]))
    back = restore(fitted)
    for a, b in zip(
        jax.tree_util.tree_leaves(back.flow.mlp), jax.tree_util.tree_leaves(model.flow.mlp), strict=True
    ):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    np.testing.assert_array_equal(np.asarray(back.flow.quadratic), [0.1, 0.2, 0.3])
    assert fresh(data, far_field="none").warmup() is None


def test_commands_compilation_cache_folder(tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "c"))
    assert default_cache_dir() == str(tmp_path / "c") and (tmp_path / "c").is_dir()
    for off in ("", "off", "OFF"):
        monkeypatch.setenv(CACHE_ENV, off)
        assert default_cache_dir() is None
    monkeypatch.delenv(CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_cache_dir() == str(tmp_path / "xdg" / "fhnn" / "jax")
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv(CACHE_ENV, str(blocker / "jax"))
    assert default_cache_dir() is None  # cannot be created: no cache, no error
