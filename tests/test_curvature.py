"""The whole-track fit's curvature: its Gauss–Newton matrix against a dense Hessian, Laplace
standard deviations against the inverse matrix, the noise level, and the directions the data
leave undetermined (masses and drag without known forcing) — on FHNN set to a simulated body's
truth (:mod:`tests.exact_fhnn`), where the residuals vanish and ``JᵀJ`` is half the Hessian."""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.flatten_util import ravel_pytree

from fhnn.evaluation.recovery import RATIO_NAMES, SUMMARY_NAMES, coefficient_medians
from fhnn.training.curvature import track_curvature
from fhnn.training.tracks import TrackFit

from .exact_fhnn import exact_data, exact_model, exact_scenario

POINTS = jnp.asarray([[1.0, 0.3], [1.5, 0.6]])  # (r, σ) [m, m/s]


@functools.cache
def _exact(actuation: str, folder: Path, noise: float = 0.0):
    """Six 3 s tracks (four to train on) with (``random``) or without (``none``) known forcing,
    their positions with ``noise`` [m] of Gaussian noise, the exact model, its fitted parameters
    and their curvature."""
    scenario = exact_scenario()
    ds = exact_data(scenario, actuation)
    model, free = exact_model(ds, scenario, folder / f"{actuation}_{noise:g}")
    states = ds.train.states.copy()
    states[..., :2] += noise * np.random.default_rng(7).normal(size=states[..., :2].shape)
    split = dataclasses.replace(ds.train, states=states)
    return ds, model, free, track_curvature(model, split, free)


@pytest.fixture(scope="module", params=["random", "none"])
def noisy(request, tmp_path_factory):
    """:func:`_exact` with 1 mm of noise."""
    return _exact(request.param, tmp_path_factory.getbasetemp(), 1e-3)


@pytest.fixture(scope="module")
def forced(tmp_path_factory):
    return _exact("random", tmp_path_factory.getbasetemp())


def _medians(ds):
    return lambda m: coefficient_medians(m.eom.coefficients, POINTS, ds.constants())


def test_the_gauss_newton_matrix_is_half_the_hessian_with_the_start_states_eliminated(forced):
    """At zero residuals ``∇²S = 2JᵀJ`` over the parameters and start states together; the Schur
    complement of the start states' block of the dense Hessian (JAX's, reverse over forward) is
    the fit's reduced matrix."""
    ds, model, free, _ = forced
    fit = TrackFit(model, free, ds.train)
    assert fit.mean_square < 1e-18  # the simulator's tolerance: rms 1e-9 m
    z = fit.z
    x = jnp.concatenate([fit.theta, z.ravel()])
    full = np.asarray(jax.jacrev(jax.grad(lambda x: _cost(fit, x, z.shape)))(x)) / 2.0
    h_tt, h_tz, h_zz = full[: fit.p, : fit.p], full[: fit.p, fit.p :], full[fit.p :, fit.p :]
    want = h_tt - h_tz @ np.linalg.solve(h_zz, h_tz.T)
    got = fit.gauss_newton()
    assert np.max(np.abs(got - want)) < 1e-7 * np.max(np.abs(want))


def _cost(fit: TrackFit, x: jax.Array, shape: tuple[int, ...]) -> jax.Array:
    """The fit's objective as one traceable function of the parameters and start states."""
    theta, z = x[: fit.p], x[fit.p :].reshape(shape)
    rows = slice(0, fit.n_tracks)
    return fit._cost(theta, z, *fit._tracks(rows))


def test_a_parameters_laplace_sd_is_the_noise_times_its_inverse_curvature(forced):
    """Every direction of the forced exact case lies above the floor but the dead ones (the
    coefficient net's ``c_l`` output, replaced by the constant): the sd of a parameter is
    ``s·√(H⁺)ₖₖ``."""
    ds, model, free, curvature = forced
    fit = TrackFit(model, free, ds.train)
    h = fit.gauss_newton()
    k = int(np.argmax(np.diag(h)))  # a parameter the data fix
    found = curvature.intervals(lambda m: jnp.atleast_1d(_theta(m, free)[k]))
    want = np.sqrt(curvature.noise_var * np.linalg.pinv(h, rcond=1e-13, hermitian=True)[k, k])
    assert found["sd"][0] == pytest.approx(want, rel=1e-6)
    assert found["hi"][0] - found["lo"][0] == pytest.approx(2 * 1.6448536 * want, rel=1e-6)


def _theta(model, free) -> jax.Array:
    """The parameters of ``model`` that ``free`` selects, as one vector (the fit's order)."""
    return ravel_pytree(eqx.partition(model, free)[0])[0]


def test_without_forcing_masses_and_drag_are_undetermined_and_their_ratios_are_not(noisy):
    """Without known forces a neutrally buoyant body's inertia and drag scale together: the
    curvature is flat along that gauge (below the floor), so with 1 mm of noise the masses,
    ``c_q``, ``c_l`` and the total drag get intervals wider than themselves (withheld), resting on
    the floor, while every ratio ``c/(M + m_a)`` is determined from the data. With known forcing
    every quantity is, none resting on the floor."""
    ds, _, _, curvature = noisy
    found = curvature.intervals(_medians(ds))
    named = lambda key: dict(zip(SUMMARY_NAMES, found[key], strict=True))  # noqa: E731
    determined, weak = named("determined"), named("weak")
    ratios = [SUMMARY_NAMES.index(n) for n in RATIO_NAMES]
    if ds.actuation == "none":
        assert ds.constants()["M"] == pytest.approx(ds.constants()["rho"] * ds.constants()["V"])
        for name in ("m_ax", "m_ay", "c_q", "c_l", "drag"):
            assert not determined[name] and weak[name], name
    else:
        assert all(determined.values())
        assert not any(weak.values())
    assert all(determined[n] and not weak[n] for n in RATIO_NAMES)
    assert np.all(found["floor_share"][ratios] < 1e-3)


def test_the_noise_level_is_estimated_from_the_residuals(noisy):
    """With 1 mm of noise on the positions, the residual variance per degree of freedom at the
    true model gives back 1 mm within 5 % (2,408 residuals: a 1.5 % standard error)."""
    ds, _, _, curvature = noisy
    assert np.sqrt(curvature.noise_var) == pytest.approx(1e-3, rel=0.05)
    assert curvature.dof == 2 * int(ds.train.mask.sum()) - curvature.theta.size - 4 * ds.train.n_traj
