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
import pytest

from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery
from fhnn.training.tracks import TrackFit

from .exact_fhnn import exact_data, exact_model, exact_scenario, raw_output

OFF = 0.2  # the start's relative error in every coefficient


@pytest.fixture(scope="module")
def recovered(tmp_path_factory):
    scenario = exact_scenario()
    ds = exact_data(scenario)
    model, free = exact_model(ds, scenario, tmp_path_factory.mktemp("recovery") / "run", OFF)
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
        lambda m: m.eom.coefficients.c_l_raw, model, jnp.asarray(raw_output(1.01 * c_l, coef.caps[3]))
    )
    free = jax.tree.map(lambda _: False, wrong)
    free = eqx.tree_at(lambda m: m.eom.coefficients.c_l_raw, free, True)
    right = TrackFit(model, free, ds.train)
    off = TrackFit(wrong, free, ds.train)
    assert off.mean_square > 1e3 * right.mean_square
