"""Flows: u = ∇⊥ψ, ∇·u = 0, the cylinder is a streamline, the material derivative."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fhnn.physics.flows import (
    CylinderFlow,
    DeepWaterWave,
    LambOseenVortex,
    SolidBodyRotation,
    SuperposedFlow,
)
from fhnn.physics.scenarios import SCENARIOS, get_scenario

H = 1e-5


def flow_of(name, rng):
    return get_scenario(name).resolve(rng).flow()


def random_points(name, rng, n=40):
    """Points in the region the scenario's bodies visit (away from the obstacle)."""
    if name == "obstacle":
        r = rng.uniform(0.6, 4.0, n)
        a = rng.uniform(0, 2 * np.pi, n)
        return np.column_stack([r * np.cos(a), r * np.sin(a)])
    if name == "wave":
        return np.column_stack([rng.uniform(-5, 5, n), rng.uniform(-3, 0, n)])
    return rng.uniform(-3, 3, (n, 2))


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_velocity_is_perp_gradient_of_stream_by_finite_differences(name, rng):
    flow = flow_of(name, rng)
    for xy in random_points(name, rng):
        t = rng.uniform(0, 20)
        psi = lambda dx, dy: float(flow.stream(jnp.asarray(xy + [dx, dy]), t))  # noqa: E731
        dpsi_dx = (psi(H, 0) - psi(-H, 0)) / (2 * H)
        dpsi_dy = (psi(0, H) - psi(0, -H)) / (2 * H)
        u = np.asarray(flow.velocity(jnp.asarray(xy), t))
        scale = max(1.0, np.abs(u).max())
        np.testing.assert_allclose(u, [dpsi_dy, -dpsi_dx], atol=2e-8 * scale)


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_divergence_free_by_finite_differences(name, rng):
    flow = flow_of(name, rng)
    for xy in random_points(name, rng):
        t = rng.uniform(0, 20)
        u = lambda dx, dy: np.asarray(flow.velocity(jnp.asarray(xy + [dx, dy]), t))  # noqa: E731
        div = (u(H, 0)[0] - u(-H, 0)[0] + u(0, H)[1] - u(0, -H)[1]) / (2 * H)
        assert abs(div) < 1e-8
        # and exactly (to rounding) by automatic differentiation
        grad = np.asarray(flow.velocity_gradient(jnp.asarray(xy), t))
        assert abs(np.trace(grad)) < 1e-13 * max(1.0, np.abs(grad).max())


def test_cylinder_is_a_streamline():
    flow = CylinderFlow(stream_speed=0.3, radius=0.5, circulation=0.5)
    for a in np.linspace(0, 2 * np.pi, 37):
        xy = jnp.asarray([0.5 * np.cos(a), 0.5 * np.sin(a)])
        assert abs(float(flow.stream(xy, 0.0))) < 1e-14
        normal = np.asarray(xy) / 0.5
        assert abs(float(np.dot(np.asarray(flow.velocity(xy, 0.0)), normal))) < 1e-14
    # far field: the uniform stream
    np.testing.assert_allclose(np.asarray(flow.velocity(jnp.asarray([1e4, 0.0]), 0.0)), [0.3, 0], atol=1e-4)


def test_only_a_flow_with_a_body_in_it_has_points_outside_the_fluid(rng):
    cylinder = CylinderFlow(stream_speed=0.3, radius=0.5, circulation=0.5)
    points = rng.uniform(-1.0, 1.0, (2000, 2))
    r = np.hypot(points[:, 0], points[:, 1])
    np.testing.assert_array_equal(cylinder.in_fluid(points), r >= 0.5)
    assert cylinder.in_fluid(np.array([[0.5, 0.0], [0.0, -0.4999]])).tolist() == [True, False]
    vortex = LambOseenVortex(gamma=5.0, core_radius=1.0)
    assert vortex.in_fluid(points).all()
    both = SuperposedFlow((vortex, cylinder))
    np.testing.assert_array_equal(both.in_fluid(points), r >= 0.5)


def test_wave_material_derivative_against_finite_differences_and_closed_form(rng):
    flow = DeepWaterWave(amplitude=0.2, period=4.0)
    a, w = 0.2, 2 * math.pi / 4.0
    k = w**2 / 9.81
    for _ in range(20):
        xy = np.array([rng.uniform(-5, 5), rng.uniform(-3, 0)])
        t = rng.uniform(0, 10)
        u = np.asarray(flow.velocity(jnp.asarray(xy), t))
        # Du/Dt is the rate of change of u seen by a fluid parcel moving with u
        ahead = np.asarray(flow.velocity(jnp.asarray(xy + H * u), t + H))
        behind = np.asarray(flow.velocity(jnp.asarray(xy - H * u), t - H))
        fd = (ahead - behind) / (2 * H)
        ad = np.asarray(flow.material_derivative(jnp.asarray(xy), t))
        np.testing.assert_allclose(ad, fd, atol=1e-9)
        th, e = k * xy[0] - w * t, math.exp(k * xy[1])
        exact = [a * w * w * e * math.sin(th), -a * w * w * e * math.cos(th) + a * a * w * w * k * e * e]
        np.testing.assert_allclose(ad, exact, atol=1e-15)


def test_lamb_oseen_profile_and_smoothness_at_the_core():
    flow = LambOseenVortex(gamma=5.0, core_radius=1.0)
    for r in (1e-4, 0.05, 0.3, 1.0, 2.0, 5.0):
        u = np.asarray(flow.velocity(jnp.asarray([r, 0.0]), 0.0))
        exact = 5.0 / (2 * math.pi * r) * -math.expm1(-(r**2))
        np.testing.assert_allclose(u, [0.0, exact], rtol=1e-13, atol=1e-16)  # counter-clockwise
    # ψ and u are finite with finite derivatives at the centre
    origin = jnp.zeros(2)
    assert np.isfinite(float(flow.stream(origin, 0.0)))
    assert np.all(np.isfinite(np.asarray(jax.jacfwd(flow.velocity)(origin, 0.0))))
    # the series branch (s < 1e-2) meets the closed form continuously
    r_switch = 0.1
    inside, outside = (flow.stream(jnp.asarray([r, 0.0]), 0.0) for r in (r_switch - 1e-9, r_switch + 1e-9))
    slope = 5.0 / (2 * math.pi * r_switch) * -math.expm1(-(r_switch**2))  # |dψ/dr| = u_θ
    assert abs(float(inside - outside) - slope * 2e-9) < 1e-14


def test_time_varying_circulation():
    flow = get_scenario("time_varying_vortex").flow()
    assert flow.time_dependent
    u0 = flow.velocity(jnp.asarray([1.0, 0.0]), 0.0)
    u5 = flow.velocity(jnp.asarray([1.0, 0.0]), 5.0)  # quarter period: Γ = 1.3 Γ0
    np.testing.assert_allclose(float(u5[1] / u0[1]), 1.3, rtol=1e-14)


def test_solid_body_rotation_hessian():
    flow = SolidBodyRotation(omega=0.2)
    hess = jax.jacrev(jax.grad(flow.stream))(jnp.asarray([0.3, -1.0]), 0.0)
    np.testing.assert_allclose(np.asarray(hess), -0.2 * np.eye(2), atol=1e-15)
    assert float(jnp.sum(hess**2)) == pytest.approx(2 * 0.2**2)
