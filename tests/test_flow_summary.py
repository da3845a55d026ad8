"""The flow summary reads a vortex's centre, circulation and core radius off its velocity, and
calls a flow that is not a vortex by its speeds and vorticity peak."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fhnn.evaluation.flow_summary import summarise_flow
from fhnn.physics.flows import AbstractFlow, LambOseenVortex

from .conftest import small_dataset


class Moved(AbstractFlow):
    """A Lamb–Oseen vortex centred at ``centre`` [m]."""

    vortex: LambOseenVortex
    centre: jax.Array

    def stream(self, xy, t):
        return self.vortex.stream(xy - self.centre, t)

    def velocity(self, xy, t):
        return self.vortex.velocity(xy - self.centre, t)


def test_a_lamb_oseen_vortex_off_the_origin_is_found() -> None:
    data = small_dataset("steady_vortex", n_traj=6)
    got = summarise_flow(Moved(LambOseenVortex(gamma=-3.0, core_radius=0.7), jnp.array([0.5, -0.3])), data)
    assert got.vortex and got.explained > 1 - 1e-9
    assert got.circulation == pytest.approx(-3.0, rel=1e-6)
    assert got.core_radius == pytest.approx(0.7, rel=1e-6)
    np.testing.assert_allclose(got.centre, (0.5, -0.3), atol=1e-6)
    assert got.peak_vorticity < 0  # clockwise


def test_a_flow_past_a_cylinder_is_no_vortex() -> None:
    data = small_dataset("obstacle", n_traj=6)
    got = summarise_flow(data.scenario_object().flow(), data)
    assert not got.vortex and got.explained < 0.9
    assert 0 <= got.speed_range[0] < got.speed_range[1]
