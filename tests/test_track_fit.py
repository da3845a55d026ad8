"""The whole-track fit (:mod:`fhnn.training.tracks`): its normal equations against finite
differences, an exactly representable truth recovered, and its place as the last training phase."""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.flatten_util import ravel_pytree

from fhnn.errors import ConfigError
from fhnn.models.baselines import MLPConfig
from fhnn.physics.actuation import forcing
from fhnn.physics.integrators import rk4_solve
from fhnn.training import tracks as track_module
from fhnn.training.run import Run, RunConfig
from fhnn.training.tracks import ForecastScore, TrackFit, origin_pieces, track_pieces

from .conftest import arrays, paper_fhnn, paper_train, small_dataset


@pytest.fixture(scope="module")
def setting(tmp_path_factory):
    """A small FHNN, a truth that differs from it in the fitted parameters only, and the
    training tracks observed exactly under that truth (start states: the data's)."""
    ds = small_dataset("steady_vortex", n_traj=6, duration=3.0)
    run = Run.create(
        tmp_path_factory.mktemp("tracks") / "run",
        ds,
        RunConfig(model=paper_fhnn(width=8), train=paper_train()),
    )
    model = run.skeleton()
    free = model.track_parameters()
    params, static = eqx.partition(model, free)
    theta, unravel = ravel_pytree(params)
    step = 0.02 * jax.random.normal(jax.random.PRNGKey(7), theta.shape) * (jnp.abs(theta) + 0.1)
    truth = eqx.combine(unravel(theta + step), static)
    sp = ds.train

    def track(s0, tt, aa, rr):
        return rk4_solve(lambda x, ti: truth(x, ti, forcing(aa, ti, tt, rr)), s0, tt)

    states = jax.vmap(track)(
        jnp.asarray(sp.states[:, 0]),
        jnp.asarray(sp.times),
        jnp.asarray(sp.actuation),
        jnp.asarray(sp.force_residual),
    )
    exact = dataclasses.replace(sp, states=np.asarray(states))
    return model, free, truth, exact


def test_only_parameters_that_move_a_residual_get_tangents(setting):
    """After the first iteration the fit builds Jacobian columns only for the parameters that
    move a residual: the coefficient net's ``c_l`` output row (weights and bias), overridden by
    the constant ``c_l``, and the stream net's output bias (a constant in ψ moves no water) are
    left out, and the next normal equations equal the full ones."""
    model, free, _, exact = setting
    fit = TrackFit(model, free, exact)
    assert fit.live is None
    full = fit._normal_equations()
    width = model.eom.coefficients.mlp.layers[-1].weight.shape[1]
    dead = np.setdiff1d(np.arange(fit.p), fit.live)
    params = eqx.partition(model, free)[0]
    stream_bias = model.eom.flow.mlp.layers[-1].bias.size
    c_l_row = np.r_[np.arange(width * 3, width * 4), width * 4 + 3]  # weight row 3, bias[3]
    coefficient_start = fit.p - width * 4 - 4 - 1  # the coefficient net's output layer, then c_l
    assert jax.tree.leaves(params)[1].size == stream_bias == 1
    np.testing.assert_array_equal(dead, np.r_[width, coefficient_start + c_l_row])
    assert np.all(full[0][dead] == 0.0) and np.all(full[1][dead] == 0.0)
    pruned = fit._normal_equations()
    for a, b in zip(full, pruned, strict=True):
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-14 * np.max(np.abs(a)))


def test_the_normal_equations_gradient_matches_finite_differences(setting):
    """``Jᵀr`` of the model's parameters and of the start states equals half the central finite
    difference of the summed squares along random directions."""
    model, free, _, exact = setting
    fit = TrackFit(model, free, exact)
    fit.z = fit.z + jnp.asarray([1e-3, -1e-3, 2e-3, 1e-3])  # off the start states' optimum
    _, g_t, _, _, g_z = fit._normal_equations()
    rng = np.random.default_rng(3)
    v_t, v_z = rng.normal(size=fit.p), rng.normal(size=fit.z.shape)
    eps = 1e-6
    for direction, grad in ((v_t, g_t), (v_z, g_z)):
        on_theta = direction is v_t

        def cost(e, direction=direction, on_theta=on_theta):
            theta = fit.theta + e * direction if on_theta else fit.theta
            z = fit.z if on_theta else fit.z + e * direction
            return fit._total_cost(theta, z)

        fd = (cost(eps) - cost(-eps)) / (2 * eps)
        want = np.sum(grad * direction)
        assert abs(want) > 1e-3 * np.linalg.norm(grad) * np.linalg.norm(direction)
        np.testing.assert_allclose(0.5 * fd, want, rtol=1e-6)


def test_a_tracks_weight_multiplies_its_squares(setting):
    """With track weights the objective is the weighted sum of the tracks' own sums of squares
    (a bootstrap member's fit), the start states being fitted in either case."""
    model, free, _, exact = setting
    weights = (1.0 + np.arange(exact.n_traj)) / 2.0
    plain = TrackFit(model, free, exact)
    weighted = TrackFit(model, free, exact, weights)
    np.testing.assert_allclose(np.asarray(weighted.z), np.asarray(plain.z)[...], rtol=0, atol=1e-12)
    each = [
        plain._cost(plain.theta, plain.z[k : k + 1], *plain._tracks(slice(k, k + 1)))
        for k in range(exact.n_traj)
    ]
    np.testing.assert_allclose(weighted.value, np.dot(weights, each), rtol=1e-12)


def test_it_recovers_an_exactly_representable_truth(setting):
    """Started from the model the truth was perturbed from, and from start states 1 mm and
    1 mm/s off, Levenberg–Marquardt drives the exact tracks' residuals twelve orders of magnitude
    down, the start states onto the true ones and the vector field along the tracks onto the
    truth's."""
    model, free, truth, exact = setting
    fit = TrackFit(model, free, exact)
    fit.z = jnp.asarray(exact.states[:, 0] + np.r_[1e-3, -1e-3, 1e-3, 1e-3])
    fit.value = fit._total_cost(fit.theta, fit.z)
    first = fit.mean_square
    for _ in range(25):
        step = fit.step()
        if not step.accepted:
            break
    assert first > 1e-8
    assert fit.mean_square < 1e-20  # rms 1e-10 m, from 1.9 mm
    np.testing.assert_allclose(np.asarray(fit.z), exact.states[:, 0], atol=1e-9)
    # the vector field along the tracks (what exact positions determine; how the drag splits
    # between c_l and c_q, say, they need not), to 1e-6 of the accelerations there (~0.1 m/s²)
    sp = exact
    for i in range(sp.n_traj):
        for k in (0, sp.n_times // 2, sp.n_times - 1):
            t = jnp.asarray(sp.times[i, k])
            force = forcing(
                jnp.asarray(sp.actuation[i]), t, jnp.asarray(sp.times[i]), jnp.asarray(sp.force_residual[i])
            )
            s = jnp.asarray(sp.states[i, k])
            np.testing.assert_allclose(
                np.asarray(fit.model(s, t, force)), np.asarray(truth(s, t, force)), rtol=1e-6, atol=1e-7
            )


def test_chord_steps_only_lower_the_objective_and_reuse_the_jacobian(setting, monkeypatch):
    """An iteration with chord steps takes the same first step as one without (the same
    normal equations, built once), then lowers the objective further with the kept Jacobian;
    the kept blocks give the exact gradient at the point they were built."""
    model, free, _, exact = setting
    plain, chord = TrackFit(model, free, exact), TrackFit(model, free, exact)
    plain.step()
    built = []
    inner = TrackFit._normal_equations
    monkeypatch.setattr(
        TrackFit, "_normal_equations", lambda self, keep=False: built.append(keep) or inner(self, keep)
    )
    chord.step(chord=3)
    assert built == [True] and chord._kept is None
    assert chord.value < 0.5 * plain.value  # the exact tracks: each chord step gains
    check = TrackFit(model, free, exact)
    _, g_t, _, _, g_z = check._normal_equations(keep=True)
    got_t, got_z = check._chord_gradient()
    np.testing.assert_allclose(got_t, g_t, rtol=1e-12, atol=1e-15 * np.abs(g_t).max())
    np.testing.assert_allclose(got_z, g_z, rtol=1e-12, atol=1e-15 * np.abs(g_z).max())


def test_it_is_the_last_phase_and_a_model_without_it_skips_it(tmp_path):
    """``train.track_steps``: after Adam, records of phase "tracks" at the steps after Adam's (the
    first saying how many tracks ``train.track_samples`` let the fit hold; the second, with
    ``track_whole=1``, in every parameter), the run finished (a second call trains nothing); a
    model that names no track parameters (the neural ODE) passes the phase without records; a
    negative count, or more matrix-free iterations than iterations, is refused."""
    ds = small_dataset("steady_vortex", n_traj=6, duration=3.0)
    # a budget one sample short of the training tracks: the fit holds all but one of them
    budget = ds.train.n_traj * ds.train.n_times - 1
    config = paper_train(
        steps=4, val_every=2, batch_size=16, track_steps=2, track_samples=budget, track_whole=1
    )
    run = Run.create(tmp_path / "fhnn", ds, RunConfig(model=paper_fhnn(width=8), train=config))
    state = run.train(ds)
    tracks = [r for r in state.history if r.get("phase") == "tracks"]
    assert tracks[0]["tracks"] == ds.train.n_traj - 1 and tracks[0]["val_tracks"] == ds.val.n_traj
    assert [r["step"] for r in tracks] == [5, 6] or (state.stopped and "whole-track" in state.stopped)
    assert all(r["track_mean_square"] > 0 and "val_total" in r for r in tracks)
    assert np.all(np.diff([r["track_mean_square"] for r in tracks]) < 0)
    # the forecasts guard's records (which iterate it keeps: the constructed cases below)
    assert tracks[0]["val_forecasts"] == ds.val.n_traj and np.isfinite(tracks[0]["val_forecast_start"])
    assert all(np.isfinite(r["val_forecast"]) and r["val_track_mean_square"] > 0 for r in tracks)
    assert run.finished and state.step == 6
    assert Run.load(tmp_path / "fhnn").finished
    before = len(state.history)
    assert len(run.train(ds).history) == before

    mlp = Run.create(tmp_path / "mlp", ds, RunConfig(kind="node", model=MLPConfig(width=8), train=config))
    state = mlp.train(ds)
    assert state.step == 6 and mlp.finished
    assert not any(r.get("phase") == "tracks" for r in state.history)
    with pytest.raises(ConfigError, match="track_steps"):
        paper_train(track_steps=-1)
    with pytest.raises(ConfigError, match=r"track_whole \(3\) counts among track_steps \(2\)"):
        paper_train(track_steps=2, track_whole=3)


def test_a_matrix_free_step_is_the_dense_gauss_newton_step(setting):
    """In every parameter of both nets, the matrix-free step (conjugate gradients on the
    normal equations with the start states projected out) equals the dense Gauss–Newton step at
    the same damping ``λI``, start states included; a fit freeing other parameters keeps the
    start states and objective; matrix-free iterations only lower the objective."""
    model, _, _, exact = setting
    whole = model.track_parameters(whole=True)
    fit = TrackFit(model, model.track_parameters(), exact).freeing(whole)
    assert fit.p > 2 * TrackFit(model, model.track_parameters(), exact).p
    tracks = fit._tracks(slice(None))
    scale, solve = track_module._matrix_free_programs(fit._resid, fit._jz, exact.n_traj, 20)
    lam = 0.1 * fit.p * float(scale(fit.theta, fit.z, *tracks))  # a tenth of the trace: well conditioned
    d_theta, d_z = solve(fit.theta, fit.z, jnp.asarray(lam), *tracks)
    _, g_t, h_tz, h_zz, g_z = fit._normal_equations()
    h_zz = h_zz + track_module._jitter(h_zz)
    reduced_g = g_t - np.einsum("npi,ni->p", h_tz, np.linalg.solve(h_zz, g_z[..., None])[..., 0])
    want = -np.linalg.solve(fit.gauss_newton() + lam * np.eye(fit.p), reduced_g)
    want_z = -np.linalg.solve(h_zz, (g_z + np.einsum("npi,p->ni", h_tz, want))[..., None])[..., 0]
    np.testing.assert_allclose(d_theta, want, rtol=1e-4, atol=1e-4 * np.abs(want).max())
    np.testing.assert_allclose(d_z, want_z, rtol=1e-4, atol=1e-4 * np.abs(want_z).max())
    values = [fit.value]
    for _ in range(3):
        assert fit.step_matrix_free(20).accepted
        values.append(fit.value)
    assert np.all(np.diff(values) < 0)


@pytest.mark.parametrize(
    ("scores", "kept"),
    [((1.0, 0.9, 1.1, 0.95, 1.2), 3), ((1.0, 1.1, 1.2, 1.3, 1.4), None), ((1.0, 0.9, 0.8, 0.7, 0.6), 4)],
    ids=["last-passing-iterate", "none-passes", "every-iterate-passes"],
)
def test_the_forecast_guard_keeps_the_last_iterate_that_forecasts_no_worse(
    tmp_path, monkeypatch, scores, kept
):
    """A constructed case whose outcome is known: the validation forecasts of the phase's start
    and of each of its four iterates are scripted (``scores``); the run's best model is the
    last iterate scoring no worse than the start (``kept``, 1-based), or, where none does,
    the model from before the phase."""
    from fhnn.training import trainer as trainer_module

    script = iter(scores)

    class Scripted:
        n_forecasts = 1

        def __init__(self, *args, **kwargs) -> None:
            pass

        def __call__(self, theta) -> float:
            return next(script)

    monkeypatch.setattr(trainer_module, "ForecastScore", Scripted)
    ds = small_dataset("steady_vortex", n_traj=6, duration=3.0)
    config = paper_train(steps=4, val_every=2, batch_size=16, track_steps=4)
    run = Run.create(tmp_path / "fhnn", ds, RunConfig(model=paper_fhnn(width=8), train=config))
    models = {}
    state = run.train(
        ds,
        callback=lambda s, r: models.update({r["iteration"]: s.model} if r.get("phase") == "tracks" else {}),
    )
    tracks = [r for r in state.history if r.get("phase") == "tracks"]
    assert [r["val_forecast"] for r in tracks] == list(scores[1:])
    assert tracks[0]["val_forecast_start"] == scores[0]
    if kept is None:
        assert state.best_val == min(r["val_total"] for r in state.history if r.get("phase") != "tracks")
        pairs = zip(arrays(state.best_model), arrays(models[4]), strict=True)
        assert any(not np.array_equal(np.asarray(a), np.asarray(b)) for a, b in pairs)
    else:
        assert state.best_val == tracks[kept - 1]["val_total"]
        for a, b in zip(arrays(state.best_model), arrays(models[kept]), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_track_pieces_cover_every_sample_once_and_keep_to_the_budget(monkeypatch):
    """A split within the budget is kept as it is; one over it is cut into pieces of at most
    ``TRACK_PIECE`` samples that together hold every real sample once, in order, at its own
    time, with its own state and force; under a tight budget as many pieces are kept as fit,
    one from each track before any track gives a second; a budget below 1 is refused."""
    monkeypatch.setattr(track_module, "TRACK_PIECE", 7)
    ds = small_dataset("steady_vortex", n_traj=10, duration=3.0)
    sp = ds.train.subset(np.arange(5))
    sp = dataclasses.replace(sp, t=np.asarray(sp.times).copy(), lengths=np.asarray([61, 20, 7, 31, 12]))
    same, parent = track_pieces(sp, sp.n_traj * sp.n_times, seed=0)
    assert same is sp and np.array_equal(parent, np.arange(sp.n_traj))

    pieces, parent = track_pieces(sp, sp.n_traj * sp.n_times - 1, seed=0)  # just over: all pieces fit
    assert np.all(pieces.sample_counts <= 7) and pieces.n_times == 7
    for i in range(sp.n_traj):
        mine = np.flatnonzero(parent == i)
        t = np.concatenate([pieces.times[j, : pieces.sample_counts[j]] for j in mine])
        s = np.concatenate([pieces.states[j, : pieces.sample_counts[j]] for j in mine])
        f = np.concatenate([pieces.forces[j, : pieces.sample_counts[j]] for j in mine])
        n = sp.sample_counts[i]
        np.testing.assert_array_equal(t, sp.times[i, :n])
        np.testing.assert_array_equal(s, sp.states[i, :n])
        np.testing.assert_array_equal(f, sp.forces[i, :n])
        np.testing.assert_array_equal(pieces.actuation[mine], sp.actuation[[i] * mine.size])
    assert np.all(np.diff(pieces.times, axis=1) > 0)  # padding times go on increasing

    few, parent = track_pieces(sp, 5 * 7 + 3, seed=3)  # room for 5 pieces of 7: one per track
    assert few.n_traj == 5 and sorted(parent) == list(range(5))
    seven, parent = track_pieces(sp, 7 * 7, seed=3)
    assert seven.n_traj == 7 and set(parent) == set(range(5))
    with pytest.raises(ConfigError, match="track_samples"):
        paper_train(track_samples=0)


def test_origin_pieces_start_at_each_origin_and_mark_their_history(monkeypatch):
    """A forecast piece from an origin every ``ORIGIN_EVERY`` s of each track: its samples are
    the track's own from that origin's sample on, up to history + ahead after it; the history
    mask holds those within ``ORIGIN_HISTORY`` s; a track too short to have a sample beyond a
    history gives none; a budget keeps as many pieces as fit; no piece at all is said."""
    monkeypatch.setattr(track_module, "ORIGIN_EVERY", 0.5)
    monkeypatch.setattr(track_module, "ORIGIN_HISTORY", 0.3)
    monkeypatch.setattr(track_module, "ORIGIN_AHEAD", 0.6)
    ds = small_dataset("steady_vortex", n_traj=10, duration=3.0)
    sp = ds.train.subset(np.arange(3))
    sp = dataclasses.replace(sp, t=np.asarray(sp.times).copy(), lengths=np.asarray([61, 25, 4]))
    step = sp.times[0, 1] - sp.times[0, 0]
    pieces, history = origin_pieces(sp, 10**6, seed=0)
    counts = [0, 0, 0]
    for j in range(pieces.n_traj):
        n = pieces.sample_counts[j]
        i = int(np.flatnonzero(np.isclose(sp.states[:, :, 0], pieces.states[j, 0, 0]).any(axis=1))[0])
        a = int(np.flatnonzero(np.isclose(sp.times[i], pieces.times[j, 0]))[0])
        counts[i] += 1
        assert np.isclose((pieces.times[j, 0] - sp.times[i, 0]) % 0.5, 0.0, atol=1e-9) or np.isclose(
            (pieces.times[j, 0] - sp.times[i, 0]) % 0.5, 0.5, atol=1e-9
        )
        np.testing.assert_array_equal(pieces.states[j, :n], sp.states[i, a : a + n])
        assert pieces.times[j, n - 1] <= pieces.times[j, 0] + 0.9 + 1e-9
        assert pieces.times[j, n - 1] > pieces.times[j, 0] + 0.3
        np.testing.assert_array_equal(history[j, :n], pieces.times[j, :n] <= pieces.times[j, 0] + 0.3 + 1e-9)
        assert not history[j, n:].any()
    # track 0: 3 s, origins at 0, 0.5, … 2.5 s with a sample beyond 0.3 s after; track 1: 1.2 s
    assert counts == [len(np.arange(0, 60 * step - 0.3, 0.5)), len(np.arange(0, 24 * step - 0.3, 0.5)), 0]
    few, _ = origin_pieces(sp, 2 * pieces.n_times, seed=1)
    assert few.n_traj == 2
    short = dataclasses.replace(sp, lengths=np.asarray([4, 4, 4]))
    _, none = origin_pieces(short, 10**6, seed=0)
    assert none.shape[0] == 0


def test_the_forecast_score_is_zero_at_the_truth(setting):
    """On tracks observed exactly under the truth, the forecast score (start states fitted to
    each history) vanishes at the truth's parameters and not at the model's."""
    model, free, truth, exact = setting
    score = ForecastScore(model, free, exact, 10**6, seed=0)
    assert score.n_forecasts == exact.n_traj  # 3 s tracks: one origin each
    truth_theta = ravel_pytree(eqx.partition(truth, free)[0])[0]
    model_theta = ravel_pytree(eqx.partition(model, free)[0])[0]
    assert score(truth_theta) < 1e-8
    assert score(model_theta) > 1e-5
