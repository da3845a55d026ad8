"""FHNN recovers a simulated body's added masses, drag and flow from actuated tracks.

The data come from the simulator (:mod:`fhnn.physics`), the model from :mod:`fhnn.models`: two
independent implementations of the equations of motion. The truth is chosen so that FHNN can
represent it exactly — the solid-body vortex (a quadratic stream function, FHNN's far-field
term), constant added masses, constant ``c_q`` and ``c_l`` — and the whole-track fit
(:class:`fhnn.training.tracks.TrackFit`) starts 20 % away from it in every coefficient and
10-20 % away in the flow. The fitted parameters are the coefficient net's output biases (the
constant added masses and ``c_q``), the constant ``c_l`` and the far-field flow; the nets' weights
stay at zero. With the full output layers free the same data trade ``c_l`` against a
speed-dependent ``c_q`` (5 % off after 30 iterations on these four tracks), so this test pins the
physics and the fit, not how well short, few tracks separate the drag laws."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery
from fhnn.physics.scenarios import get_scenario
from fhnn.training.run import Run, RunConfig
from fhnn.training.tracks import TrackFit

OFF = 0.2  # the start's relative error in every coefficient


def _raw(value: float, cap: float) -> float:
    """The raw output whose capped map ``C·tanh(softplus(z)/C)`` is ``value``."""
    return float(np.log(np.expm1(cap * np.arctanh(value / cap))))


@pytest.fixture(scope="module")
def recovered(tmp_path_factory):
    scenario = get_scenario("solid_body_vortex").replace(m_a_amplitude=0.0, area=0.04, c_l=8.0)
    config = SimulationConfig.for_scenario(
        scenario, n_traj=6, duration=3.0, test_duration=3.0, actuation="random", actuation_amplitude=20.0
    )
    ds = simulate_dataset(scenario, config)
    model = Run.create(tmp_path_factory.mktemp("recovery") / "run", ds, RunConfig()).skeleton()
    coef = model.eom.coefficients
    assert coef.c_l_raw is not None and coef.mass_raw is None
    start = np.array([scenario.m_a_base, scenario.m_a_base, scenario.c_q, scenario.c_l])
    start = start * (1.0 + OFF * np.array([1.0, -1.0, 1.0, 1.0]))
    raw = jnp.asarray([_raw(v, c) for v, c in zip(start, coef.caps, strict=True)])
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
    # the far-field flow that equals the truth (least squares over points; exact for a quadratic
    # stream function), then moved off it
    points = jnp.asarray(np.random.default_rng(0).uniform(-3.0, 3.0, (200, 2)))
    true_flow = ds.equations().flow

    def velocities(p):
        m = eqx.tree_at(lambda m: (m.eom.flow.quadratic, m.eom.flow.linear), model, (p[:3], p[3:]))
        return jax.vmap(lambda xy: m.eom.flow.velocity(xy, 0.0))(points).ravel()

    design = np.asarray(jax.jacfwd(velocities)(jnp.zeros(5)))
    want = np.asarray(jax.vmap(lambda xy: true_flow.velocity(xy, 0.0))(points)).ravel()
    p, *_ = np.linalg.lstsq(design, want, rcond=None)
    assert np.max(np.abs(design @ p - want)) < 1e-12  # FHNN's far field holds this flow exactly
    model = eqx.tree_at(
        lambda m: (m.eom.flow.quadratic, m.eom.flow.linear),
        model,
        (jnp.asarray(p[:3] * (1.0 + OFF / 2)), jnp.asarray(p[3:] + 0.02)),
    )
    free = jax.tree.map(lambda _: False, model)
    for pick in (
        lambda m: m.eom.coefficients.mlp.layers[-1].bias,
        lambda m: m.eom.coefficients.c_l_raw,
        lambda m: m.eom.flow.quadratic,
        lambda m: m.eom.flow.linear,
    ):
        free = eqx.tree_at(pick, free, True)
    fit = TrackFit(model, free, ds.train)
    first = fit.mean_square
    for _ in range(40):
        if not fit.step().accepted:
            break
    return ds, model, fit, first


def test_masses_drag_and_flow_are_recovered_to_a_millionth(recovered):
    """From 20 % off, the fit drives the tracks' mean square from 8e-5 m² (rms 9 mm) to below 1e-18 m²
    (rms 1 nm, the simulator's tolerance) and every coefficient onto the truth within 1e-5 of
    its value — a tenth of a thousandth of the 1 % a wrong ``c_l`` would be off — and the flow
    within 1e-6."""
    ds, start, fit, first = recovered
    before = coefficient_recovery(start.eom.coefficients, ds)
    after = coefficient_recovery(fit.model.eom.coefficients, ds)
    assert first > 1e-5
    assert fit.mean_square < 1e-18
    for name in ("m_ax", "m_ay", "c_q", "c_l"):
        assert before[name]["max_rel"] == pytest.approx(OFF, rel=1e-9)
        assert after[name]["max_rel"] < 1e-5, (name, after[name])
    assert flow_recovery(start.eom.flow, ds)["rel_l2"] > 0.05
    assert flow_recovery(fit.model.eom.flow, ds)["rel_l2"] < 1e-6


def test_a_one_percent_wrong_linear_drag_is_not_a_fit(recovered):
    """The same tracks with ``c_l`` held 1 % off its recovered value (everything else as
    recovered) fit a thousand times worse: the test above would see a 1 % error."""
    ds, _, fit, _ = recovered
    model = fit.model
    coef = model.eom.coefficients
    c_l = float(coef(jnp.asarray(1.0), jnp.asarray(0.5))[3])
    wrong = eqx.tree_at(
        lambda m: m.eom.coefficients.c_l_raw, model, jnp.asarray(_raw(1.01 * c_l, coef.caps[3]))
    )
    free = jax.tree.map(lambda _: False, wrong)
    free = eqx.tree_at(lambda m: m.eom.coefficients.c_l_raw, free, True)
    right = TrackFit(model, free, ds.train)
    off = TrackFit(wrong, free, ds.train)
    assert off.mean_square > 1e3 * right.mean_square
