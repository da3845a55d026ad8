"""An FHNN set to represent a simulated body exactly, for tests of the fit and its curvature.

The truth is the solid-body vortex (a quadratic stream function: FHNN's far-field term) with
constant added masses, ``c_q`` and ``c_l``; FHNN holds it with its nets' weights at zero, the
coefficient net's output biases set to the constant masses and ``c_q``, the constant ``c_l`` and
the far field fitted to the flow (exactly: a least-squares fit with residuals below 1e-12)."""

from __future__ import annotations

from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.data.dataset import Dataset
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.physics.scenarios import Scenario, get_scenario
from fhnn.training.run import Run, RunConfig


def exact_scenario() -> Scenario:
    """The solid-body vortex with constant added masses (``m_a_amplitude`` 0), area 0.04 m² and
    ``c_l`` 8 N·s/m, so that ``c_q``'s and ``c_l``'s parts of the drag are both large."""
    return get_scenario("solid_body_vortex").replace(m_a_amplitude=0.0, area=0.04, c_l=8.0)


def exact_data(scenario: Scenario, actuation: str = "random", **fields: object) -> Dataset:
    """Six 3 s tracks of ``scenario`` with ``actuation`` (amplitude 20 N)."""
    config = SimulationConfig.for_scenario(
        scenario,
        **{"n_traj": 6, "duration": 3.0, "test_duration": 3.0, "actuation_amplitude": 20.0, **fields},
        actuation=actuation,
    )
    return simulate_dataset(scenario, config)


def raw_output(value: float, cap: float) -> float:
    """The raw output whose capped map ``C·tanh(softplus(z)/C)`` is ``value``."""
    return float(np.log(np.expm1(cap * np.arctanh(value / cap))))


def exact_model(ds: Dataset, scenario: Scenario, folder: Path, off: float = 0.0) -> tuple[eqx.Module, object]:
    """FHNN holding ``scenario``'s truth, moved ``off`` (relative) away from it: the masses and
    drag by ``off`` (``m_ay`` down, the others up), the far field's quadratic part by ``off/2``
    and its linear part by 0.02 where ``off`` is not 0. Returns the model and the filter of its
    fitted parameters (the coefficient net's output biases, the constant ``c_l`` and the far
    field)."""
    model = Run.create(folder, ds, RunConfig()).skeleton()
    coef = model.eom.coefficients
    assert coef.c_l_raw is not None and coef.mass_raw is None
    start = np.array([scenario.m_a_base, scenario.m_a_base, scenario.c_q, scenario.c_l])
    start = start * (1.0 + off * np.array([1.0, -1.0, 1.0, 1.0]))
    raw = jnp.asarray([raw_output(v, c) for v, c in zip(start, coef.caps, strict=True)])
    last = coef.mlp.layers[-1]
    model = eqx.tree_at(
        lambda m: m.eom.coefficients.mlp.layers[-1].weight, model, jnp.zeros_like(last.weight)
    )
    model = eqx.tree_at(lambda m: m.eom.coefficients.mlp.layers[-1].bias, model, raw)
    model = eqx.tree_at(lambda m: m.eom.coefficients.c_l_raw, model, raw[3])
    flow_last = model.eom.flow.mlp.layers[-1]
    model = eqx.tree_at(
        lambda m: (m.eom.flow.mlp.layers[-1].weight, m.eom.flow.mlp.layers[-1].bias),
        model,
        (jnp.zeros_like(flow_last.weight), jnp.zeros_like(flow_last.bias)),
    )
    points = jnp.asarray(np.random.default_rng(0).uniform(-3.0, 3.0, (200, 2)))
    true_flow = ds.equations().flow

    def velocities(p):
        m = eqx.tree_at(lambda m: (m.eom.flow.quadratic, m.eom.flow.linear), model, (p[:3], p[3:]))
        return jax.vmap(lambda xy: m.eom.flow.velocity(xy, 0.0))(points).ravel()

    design = np.asarray(jax.jacfwd(velocities)(jnp.zeros(5)))
    want = np.asarray(jax.vmap(lambda xy: true_flow.velocity(xy, 0.0))(points)).ravel()
    p, *_ = np.linalg.lstsq(design, want, rcond=None)
    assert np.max(np.abs(design @ p - want)) < 1e-12  # FHNN's far field holds this flow exactly
    shift = 0.02 if off else 0.0
    model = eqx.tree_at(
        lambda m: (m.eom.flow.quadratic, m.eom.flow.linear),
        model,
        (jnp.asarray(p[:3] * (1.0 + off / 2)), jnp.asarray(p[3:] + shift)),
    )
    free = jax.tree.map(lambda _: False, model)
    for pick in (
        lambda m: m.eom.coefficients.mlp.layers[-1].bias,
        lambda m: m.eom.coefficients.c_l_raw,
        lambda m: m.eom.flow.quadratic,
        lambda m: m.eom.flow.linear,
    ):
        free = eqx.tree_at(pick, free, True)
    return model, free
