"""The trainer's compiled programs: traced once per shape and structure (the Adam phase's numbers
are arguments), the penalty-free Adam step, the warm-up part without the stream MLP, and the
commands' compilation cache folder."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

import fhnn.executables as executables
import fhnn.training.losses as losses_module
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.errors import ConfigError
from fhnn.models.baselines import MLPConfig
from fhnn.models.registry import MODELS
from fhnn.physics.scenarios import get_scenario
from fhnn.runtime import CACHE_ENV, default_cache_dir
from fhnn.training.run import Run
from fhnn.training.trainer import (
    PENALTY_FREE_MIN_STEPS,
    AdamSettings,
    Trainer,
    adam_step,
)

from .conftest import SMALL, arrays, paper_fhnn, paper_train, small_dataset


@pytest.fixture(scope="module")
def data():
    return small_dataset("steady_vortex", n_traj=6, duration=2.0)


def fresh(data, seed=0, **model):
    return MODELS["fhnn"].make(paper_fhnn(width=8, depth=2, **model), MODELS["fhnn"].arguments(data), seed)


@pytest.fixture
def traces(monkeypatch):
    """A list that grows by one each time the trainer's loss is traced (run in Python). Stored
    executables are off: one another test or process stored would be loaded untraced."""
    monkeypatch.setattr(executables, "store_folder", lambda: None)
    calls = []
    original = losses_module.loss_terms

    def counting(model, batch, scales):
        calls.append(1)
        return original(model, batch, scales)

    monkeypatch.setattr(losses_module, "loss_terms", counting)
    return calls


def test_a_second_trainer_of_the_same_shapes_traces_nothing(data, traces):
    """The Adam step, the validation and the quasi-Newton iteration read data, scales and keys as
    arguments, the Adam phase's numbers too (:class:`AdamSettings`), and only what shapes a
    program as static configuration: a second run with another seed, validation interval, number
    of steps, learning rate and schedule, and flow penalty reuses all three programs (no Python
    trace of the loss at all). A zero weight, which drops a loss term, is another program."""

    def train(seed, val_every, **numbers):
        config = paper_train(
            val_every=val_every, batch_size=16, lbfgs_steps=2, lbfgs_pairs=64, seed=seed, **numbers
        )
        tr = Trainer(config, data.train, data.val)
        state = tr.run(tr.init(fresh(data, seed)))
        tr.polish(state)
        return len(traces)

    first = train(0, 2, steps=4)
    assert first > 0
    other = dict(steps=6, lr=1e-3, lr_decay=0.5, lr_boundaries=(0.2, 0.5, 0.7, 0.95))
    assert train(7, 4, **other, lambda_flow=3e-6, flow_anneal=0.3) == first  # nothing traced again
    structure = lambda **c: jax.tree.structure(AdamSettings.of(paper_train(**c)))  # noqa: E731
    assert structure(seed=1, val_every=3, **other) == structure()
    assert structure(w_step=0.0) != structure() and structure(lr_c_l=3.0) != structure()


@pytest.mark.parametrize(
    "config",
    [
        paper_train(),
        paper_train(steps=2, lr_c_l=3.0),  # boundaries that fall on one step count once
        paper_train(steps=7, lr_boundaries=(), flow_anneal=0.0, w_step=0.0),
        paper_train(steps=1000, lr_boundaries=(0.5,), lr=1e-2, lr_decay=0.1, flow_anneal=0.3),
    ],
)
def test_adam_settings_compute_the_configurations_schedule_penalty_weight_and_loss_exactly(config):
    """The learning rate is optax's piecewise-constant schedule of the configuration, bit for bit;
    the penalty's weight decays linearly from ``lambda_flow`` to 0 over ``flow_anneal`` of the steps."""
    settings = AdamSettings.of(config)
    schedule = optax.piecewise_constant_schedule(
        config.lr, {int(b * config.steps): config.lr_decay for b in config.lr_boundaries}
    )
    end = config.flow_anneal * config.steps
    edges = [int(b * config.steps) + d for b in config.lr_boundaries for d in (-1, 0, 1)]
    for i in sorted({*range(min(config.steps + 2, 40)), *edges, config.steps - 1}):
        count = jnp.asarray(max(i, 0), jnp.int32)
        assert float(settings.rate(count)) == float(schedule(count))
        weight = config.lambda_flow * min(max(1.0 - max(i, 0) / end, 0.0), 1.0) if end > 0 else 0.0
        assert float(settings.flow_weight(count)) == weight
    terms = {"deriv": jnp.asarray(0.3), "step": jnp.asarray(0.7), "flow": jnp.asarray(5.0)}
    assert float(settings.data_loss(terms)) == float(losses_module.data_loss(terms, config))


def test_the_quasi_newton_step_compiles_once_per_phase(data, traces):
    """optax's L-BFGS starts its line-search info as weakly typed scalars and returns them strong:
    the trainer strengthens the initial state, so a 3-iteration polish traces the loss exactly as
    often as a 1-iteration one (before the fix the second iteration compiled the step again)."""

    def polish_traces(width, iterations):
        config = paper_train(steps=0, val_every=1, lbfgs_steps=iterations, lbfgs_pairs=64)
        tr = Trainer(config, data.train, data.val)
        kind = MODELS["node"]  # the cheapest model to compile: the issue is the optimiser's state
        state = tr.init(kind.make(MLPConfig(width=width, depth=1), kind.arguments(data), 0))
        before = len(traces)
        tr.polish(state)
        return len(traces) - before

    once = polish_traces(5, 1)
    assert once > 0
    assert polish_traces(6, 3) == once


def test_other_data_bodies_and_ablations_share_the_programs_and_never_move_the_constants(data, traces):
    """FHNN's data-derived constants (input scales, radius range, body mass, ρ, A, V) and the
    ablation mask are array leaves behind stop_gradient, not static fields: a model of the same
    architecture on another scenario (other body, other scales) or with the added mass or linear
    drag ablated runs the same compiled Adam step — nothing is traced again — and training leaves
    every constant bit-identical."""
    scenario = get_scenario("obstacle", mass=14.0, area=0.03)
    other = simulate_dataset(
        scenario,
        SimulationConfig.for_scenario(scenario, **{**SMALL, "n_traj": 6, "duration": 2.0, "dt": data.dt}),
    )
    assert other.constants()["M"] != data.constants()["M"]
    assert len(Trainer(paper_train(), other.train, other.val).train_pairs) == len(
        Trainer(paper_train(), data.train, data.val).train_pairs
    )
    config = paper_train(steps=3, val_every=3, batch_size=16)

    def train(dataset, **model):
        tr = Trainer(config, dataset.train, dataset.val)
        start = fresh(dataset, **model)
        end = tr.run(tr.init(start)).model
        return start, end, len(traces)

    start, end, first = train(data)
    constants = lambda m: (  # noqa: E731
        m.flow.length_scale, m.flow.psi_scale, m.flow.time_scale, m.coefficients.r_scale,
        m.coefficients.sigma_scale, m.coefficients.r_range, m.coefficients.mask,
        m.eom.mass, m.eom.rho, m.eom.area, m.eom.volume,
    )  # fmt: skip
    for a, b in zip(constants(start), constants(end), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert any(not np.array_equal(a, b) for a, b in zip(arrays(start), arrays(end), strict=True))
    for model in ({}, {"ablation": "no_added_mass"}, {"ablation": "no_linear_drag"}):
        s2, e2, count = train(other, **model)
        assert count == first, model  # the same program
        assert float(e2.eom.mass) == other.constants()["M"] != float(end.eom.mass)
        for a, b in zip(constants(s2), constants(e2), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # the constants do matter: the ablation mask is what switches the added mass off
    coefs = lambda m: np.asarray(m.coefficients(jnp.asarray(1.0), jnp.asarray(0.2)))  # noqa: E731
    assert coefs(fresh(data, ablation="no_added_mass"))[:2].tolist() == [0.0, 0.0]
    assert np.all(coefs(fresh(data))[:2] > 0)


def test_a_format_1_run_loads_with_its_constants_and_predicts_as_it_did(tmp_path):
    """A run saved before the constants were arrays (run format 1: fixture written by fhnn at
    commit 32d21a1) loads, resumes its optimiser state, and predicts what it predicted then."""
    fixture = Path(__file__).parent / "fixtures" / "run_format1"
    shutil.copytree(fixture, tmp_path / "f")
    run = Run.load(tmp_path / "f" / "run")
    assert json.loads((tmp_path / "f" / "run" / "run.json").read_text())["format_version"] == 1
    expected = json.loads((fixture / "expected.json").read_text())
    s, t, f = (jnp.asarray(expected[k]) for k in ("states", "t", "force"))
    for name, model in (("model", run.state.model), ("best", run.state.best_model)):
        np.testing.assert_allclose(
            np.asarray(jax.vmap(model)(s, t, f)), expected[name], rtol=1e-13, atol=1e-15
        )
    assert float(run.state.model.flow.length_scale) == run.args["length_scale"]
    assert np.asarray(run.state.model.coefficients.r_range).tolist() == run.args["r_range"]
    # the Adam state of a format-1 run has zero moments for the constants and goes on training
    mu = run.state.opt_state[0].mu
    assert float(mu.eom.mass) == 0.0 and float(mu.eom.flow.length_scale) == 0.0
    assert np.any(np.asarray(mu.eom.flow.linear) != 0)
    dataset = run.dataset()
    config = run.train_config
    tr = Trainer(config, dataset.train, dataset.val)
    args = (run.state.model, run.state.opt_state, jnp.asarray(1), tr._train, tr.scales, tr._key, None)
    moved, opt_state, terms = adam_step(*args, AdamSettings.of(config), True)
    assert terms["skipped"] == 0.0 and float(moved.eom.mass) == float(run.state.model.eom.mass)
    run.state.model, run.state.opt_state = moved, opt_state
    run.save()
    again = Run.load(tmp_path / "f" / "run")
    assert json.loads((tmp_path / "f" / "run" / "run.json").read_text())["format_version"] == 2
    np.testing.assert_array_equal(
        np.asarray(jax.vmap(again.state.model)(s, t, f)), np.asarray(jax.vmap(run.state.model)(s, t, f))
    )


def test_the_penalty_free_step_is_the_same_step_once_the_weight_is_zero(data):
    config = paper_train(steps=4 * PENALTY_FREE_MIN_STEPS, batch_size=32)
    end = int(config.flow_anneal * config.steps)
    assert config.regularizes(end - 1) and not config.regularizes(end)
    # a short run keeps one program: too few steps to gain a second compilation back
    short = paper_train(steps=PENALTY_FREE_MIN_STEPS)
    assert all(short.regularizes(i) for i in (0, short.steps // 2, short.steps - 1))
    assert not paper_train(lambda_flow=0.0).regularizes(0)
    tr = Trainer(config, data.train, data.val)
    state = tr.init(fresh(data, far_field="none"))  # the whole ψ is penalised: non-zero from the start
    args = (state.model, state.opt_state, jnp.asarray(end + 3), tr._train, tr.scales, tr._key, None)
    with_penalty = adam_step(*args, AdamSettings.of(config), True)
    without = adam_step(*args, AdamSettings.of(config), False)
    assert "flow" in with_penalty[2] and "flow" not in without[2]
    for a, b in zip(arrays(with_penalty[:2]), arrays(without[:2]), strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-13, atol=1e-15)
    # before the end of the anneal the penalty is in the loss
    early = (state.model, state.opt_state, jnp.asarray(0), tr._train, tr.scales, tr._key, None)
    terms = adam_step(*early, AdamSettings.of(config), True)[2]
    data_only = adam_step(*early, AdamSettings.of(config), False)[2]["loss"]
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


def test_lr_c_l_scales_only_the_constant_coefficients_steps(data):
    """``train.lr_c_l = K``: Adam's first update of ``c_l_raw`` and of constant added masses'
    ``mass_raw`` is K times the plain one (Adam's first step is the rate times g/(|g| + ε)),
    every other parameter's is identical."""
    model = fresh(data, added_mass="constant")
    updates = {}
    for k in (1.0, 7.0):
        config = paper_train(steps=10, batch_size=16, lr_c_l=k)
        tr = Trainer(config, data.train, data.val)
        state = tr.init(model)
        args = (state.model, state.opt_state, jnp.asarray(0), tr._train, tr.scales, tr._key, None)
        moved = adam_step(*args, AdamSettings.of(config), True)[0]
        updates[k] = jax.tree_util.tree_map(
            lambda a, b: np.asarray(a - b), eqx.filter(moved, eqx.is_array), eqx.filter(model, eqx.is_array)
        )
    c_l = lambda u: float(u.eom.coefficients.c_l_raw)  # noqa: E731
    assert abs(c_l(updates[1.0])) > 1e-4  # it moved, by about the rate (3e-3)
    assert c_l(updates[7.0]) == pytest.approx(7.0 * c_l(updates[1.0]), rel=1e-9)
    masses = lambda u: np.asarray(u.eom.coefficients.mass_raw)  # noqa: E731
    assert np.all(np.abs(masses(updates[1.0])) > 1e-4)
    np.testing.assert_allclose(masses(updates[7.0]), 7.0 * masses(updates[1.0]), rtol=1e-9)
    rest = lambda u: eqx.tree_at(  # noqa: E731
        lambda m: (m.eom.coefficients.c_l_raw, m.eom.coefficients.mass_raw), u, (np.zeros(()), np.zeros(2))
    )
    for a, b in zip(arrays(rest(updates[1.0])), arrays(rest(updates[7.0])), strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ConfigError, match="lr_c_l must be > 0, got 0.0"):
        paper_train(lr_c_l=0.0)
