"""Where a table's origin lies, and which way its axes point, is the tracker's choice: a model of
imported data must not depend on it. A translated table gives the same model and forecasts to
rounding. A rotated table gives the rotated data set, and the model built for it holds the
rotated model of the original exactly (its flow net's first layer turned): the two trainings differ
only as two initial draws do (``benchmarks/frame_invariance.py`` measures by how much). A body
with ``m_ax ≠ m_ay`` is not symmetric under rotation: the point body keeps its orientation, so
its added-mass axes are the table's; the rotation checks use an isotropic body."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest

import fhnn
from fhnn.data.observation import observe
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.models.registry import MODELS
from fhnn.physics.scenarios import get_scenario
from fhnn.training.run import RunConfig

SHIFT = np.array([100.0, -50.0])
ANGLE = np.pi / 6
TURN = np.array([[np.cos(ANGLE), -np.sin(ANGLE)], [np.sin(ANGLE), np.cos(ANGLE)]])
#: A short Adam-only training: what is compared is the pipeline, not a converged model.
QUICK = {"train.steps": 40, "train.lbfgs_steps": 0, "train.track_steps": 0, "train.val_every": 20}


def moved(table: dict[str, np.ndarray], turn: np.ndarray, shift: np.ndarray) -> dict[str, np.ndarray]:
    """``table`` with its positions turned by ``turn`` ``(2, 2)`` and moved by ``shift`` [m], its
    forces turned."""
    out = dict(table)
    for a, b in (("x", "y"), ("Fx", "Fy")):
        both = np.stack([table[a], table[b]], axis=-1) @ turn.T
        if a == "x":
            both = both + shift
        out[a], out[b] = both[:, 0], both[:, 1]
    return out


@pytest.fixture(scope="module")
def table() -> dict[str, np.ndarray]:
    """An isotropic body in the steady vortex with sinusoidal thrust, observed with 1 mm noise and
    one 0.3 m glitch."""
    scenario = dataclasses.replace(get_scenario("steady_vortex"), m_ax=16.0, m_ay=16.0)
    config = SimulationConfig.for_scenario(scenario, n_traj=8, duration=4.0, test_duration=4.0, dt=0.01)
    table = observe(simulate_dataset(scenario, config), step=0.05, jitter=0.3, noise=1e-3, seed=2)
    table["x"][np.flatnonzero(table["traj_id"] == 1)[20]] += 0.3  # a glitch to drop, turned or not
    return table


def _import(table: dict[str, np.ndarray]) -> fhnn.Dataset:
    return fhnn.import_table(pd.DataFrame(table), mass=10.0, area=0.02)


def _turned(states: np.ndarray, turn: np.ndarray, shift: np.ndarray) -> np.ndarray:
    out = np.array(states)
    out[..., :2] = states[..., :2] @ turn.T + shift
    out[..., 2:] = states[..., 2:] @ turn.T
    return out


def test_a_translated_table_gives_the_same_model_and_forecast(table, tmp_path: Path) -> None:
    same = np.eye(2)
    fits = [
        fhnn.train(_import(moved(table, same, s)), tmp_path / name, settings=QUICK, progress=False)
        for name, s in (("here", np.zeros(2)), ("there", SHIFT))
    ]
    here, there = (f.models[0] for f in fits)
    np.testing.assert_allclose(np.asarray(there.eom.origin) - np.asarray(here.eom.origin), SHIFT, atol=1e-9)
    for a, b in zip(
        jax.tree_util.tree_leaves(eqx.filter(here, eqx.is_array)),
        jax.tree_util.tree_leaves(eqx.filter(there, eqx.is_array)),
        strict=True,
    ):
        if a.shape != (2,):  # every weight and constant but the origin
            np.testing.assert_allclose(np.asarray(b), np.asarray(a), rtol=1e-7, atol=1e-9)
    history = {k: v[(table["traj_id"] == 0) & (table["t"] <= 1.0)] for k, v in table.items()}
    forecasts = [
        f.predict(2.0, history=pd.DataFrame(moved(history, same, s)), samples=0).columns
        for f, s in zip(fits, (np.zeros(2), SHIFT), strict=True)
    ]
    for axis, offset in zip("xy", SHIFT, strict=True):
        np.testing.assert_allclose(forecasts[1][axis] - offset, forecasts[0][axis], atol=1e-7)


@pytest.mark.parametrize("smoother", ["spline", "kalman"])
def test_a_rotated_table_gives_the_rotated_data_set(table, smoother: str) -> None:
    """Positions, velocities, forces, the noise level and the centre turn with the table: the
    noise level pools residual vectors' lengths, the spline fits a track's axes as one curve."""
    here = fhnn.import_table(pd.DataFrame(table), mass=10.0, area=0.02, smoother=smoother)
    there = fhnn.import_table(
        pd.DataFrame(moved(table, TURN, SHIFT)), mass=10.0, area=0.02, smoother=smoother
    )
    for name in ("train", "val", "test"):
        a, b = here[name], there[name]
        want = _turned(a.states[a.mask], TURN, SHIFT)
        np.testing.assert_allclose(b.states[b.mask][:, :2], want[:, :2], atol=1e-9)
        np.testing.assert_allclose(b.forces[b.mask], a.forces[a.mask] @ TURN.T, atol=1e-9)
        np.testing.assert_allclose(b.states[b.mask][:, 2:], want[:, 2:], atol=1e-9)
    np.testing.assert_allclose(there.centre, TURN @ here.centre + SHIFT, atol=1e-9)
    assert here.extra["import"]["outliers_dropped"] == there.extra["import"]["outliers_dropped"] == 1
    assert there.extra["import"]["position_noise"] == pytest.approx(
        here.extra["import"]["position_noise"], rel=0.05
    )


def test_the_model_for_a_rotated_table_holds_the_rotated_model(table) -> None:
    here, there = _import(table), _import(moved(table, TURN, SHIFT))
    kind = MODELS["fhnn"]
    config = RunConfig().model
    a = kind.make(config, kind.arguments(here), 3)
    b = kind.make(config, kind.arguments(there), 4)
    for name in ("length_scale", "psi_scale"):  # the data-derived constants do not turn
        np.testing.assert_allclose(getattr(b.eom.flow, name), getattr(a.eom.flow, name), rtol=1e-9)
    np.testing.assert_allclose(b.eom.coefficients.r_range, a.eom.coefficients.r_range, rtol=1e-9)
    # a's weights in b's frame: ξ' = Rξ, so the first layer takes Rᵀξ', Q' = RQRᵀ, b' = Rb; the
    # MLP's last layer and the far field drawn at random (at the start they give no flow)
    k1, k2, k3 = jax.random.split(jax.random.PRNGKey(5), 3)
    mlp = a.eom.flow.mlp
    mlp = eqx.tree_at(
        lambda n: n.layers[-1].weight, mlp, 0.3 * jax.random.normal(k1, mlp.layers[-1].weight.shape)
    )
    q = 0.3 * jax.random.normal(k2, (3,))
    lin = 0.3 * jax.random.normal(k3, (2,))
    turn = jnp.asarray(TURN)
    q_turned = turn @ jnp.array([[q[0], q[1]], [q[1], q[2]]]) @ turn.T
    parts = lambda m: (m.eom.flow.mlp, m.eom.flow.quadratic, m.eom.flow.linear, m.eom.coefficients)  # noqa: E731
    last = a.eom.coefficients.mlp.layers[-1]  # an isotropic body: m_ay's output row is m_ax's
    coefficients = eqx.tree_at(
        lambda c: (c.mlp.layers[-1].weight, c.mlp.layers[-1].bias),
        a.eom.coefficients,
        (last.weight.at[1].set(last.weight[0]), last.bias.at[1].set(last.bias[0])),
    )
    a = eqx.tree_at(parts, a, (mlp, q, lin, coefficients))
    mlp_turned = eqx.tree_at(lambda n: n.layers[0].weight, mlp, mlp.layers[0].weight @ turn.T)
    q3 = jnp.array([q_turned[0, 0], q_turned[0, 1], q_turned[1, 1]])
    b = eqx.tree_at(parts, b, (mlp_turned, q3, turn @ lin, a.eom.coefficients))
    states = here.train.states[here.train.mask][::9]
    forces = here.train.forces[here.train.mask][::9]
    t = here.train.times[here.train.mask][::9]
    got = jax.vmap(b)(jnp.asarray(_turned(states, TURN, SHIFT)), jnp.asarray(t), jnp.asarray(forces @ TURN.T))
    want = jax.vmap(a)(jnp.asarray(states), jnp.asarray(t), jnp.asarray(forces))
    np.testing.assert_allclose(
        np.asarray(got), _turned(np.asarray(want), TURN, np.zeros(2)), rtol=1e-9, atol=1e-12
    )
