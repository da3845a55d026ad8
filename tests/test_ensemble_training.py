"""An ensemble's Adam phases trained as one ``vmap``-ed program
(:func:`fhnn.training.together.run_together`): the same members as trained one after another, a
member whose guard fires leaves the group, and what cannot run together is recognised."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

import fhnn.training.ensemble as ensemble_module
import fhnn.training.trainer as trainer_module
from fhnn.training.ensemble import interval, train_members
from fhnn.training.run import Run, RunConfig
from fhnn.training.sampling import bootstrap_weights, draw_batch
from fhnn.training.together import can_run_together
from fhnn.training.trainer import Trainer

from .conftest import arrays, paper_fhnn, paper_train, small_dataset

CONFIG = paper_train(steps=24, val_every=8, batch_size=16, lbfgs_steps=3, lbfgs_pairs=64, lambda_flow=1e-6)


@pytest.fixture(scope="module")
def data():
    return small_dataset("steady_vortex", n_traj=4, duration=1.0)


def members(folder, ds, seeds=(0, 1, 2), config=CONFIG):
    folder.mkdir(exist_ok=True)
    return [
        Run.create(
            folder / f"seed-{s}", ds, RunConfig(model=paper_fhnn(width=8), train=config.replace(seed=s))
        )
        for s in seeds
    ]


def assert_same_run(a: Run, b: Run) -> None:
    """Same records (step for step, losses to 1e-9 relative) and the same weights (1e-7)."""
    assert [r["step"] for r in a.state.history] == [r["step"] for r in b.state.history]
    for ra, rb in zip(a.state.history, b.state.history, strict=True):
        assert ra.keys() == rb.keys()
        for key, value in ra.items():
            if isinstance(value, float):
                np.testing.assert_allclose(value, rb[key], rtol=1e-9, atol=1e-300, err_msg=key)
    for x, y in zip(arrays(a.state.best_model), arrays(b.state.best_model), strict=True):
        np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=1e-7, atol=1e-12)


@pytest.mark.parametrize("bootstrap", [False, True])
def test_members_trained_together_are_the_members_trained_alone(tmp_path, data, monkeypatch, bootstrap):
    """Three members' Adam phases as one program, each with the flow penalty (annealed) and the
    polish after (and each on its own bootstrap resample: their window weights ride along as one
    more stacked argument): every record and the final weights are those of the members trained
    alone; each member's checkpoint on disk is its final state."""
    config = CONFIG.replace(bootstrap=bootstrap)
    together = members(tmp_path / "together", data, config=config)
    alone = members(tmp_path / "alone", data, config=config)
    records: list[list[int]] = [[], [], []]
    callbacks = [lambda state, record, j=j: records[j].append(record["step"]) for j in range(3)]
    groups = []
    real = ensemble_module.run_together
    monkeypatch.setattr(
        ensemble_module,
        "run_together",
        lambda trainers, *a, **k: groups.append(len(trainers)) or real(trainers, *a, **k),
    )
    train_members(together, data, callbacks=callbacks)
    assert groups == [3]
    train_members(alone, data, together=False)
    for a, b in zip(together, alone, strict=True):
        assert a.finished and a.state.step == 27
        assert_same_run(a, b)
        assert_same_run(Run.load(a.folder), b)
    assert records == [[8, 16, 24, 25, 26, 27]] * 3  # three Adam records, three polish iterations
    # the members differ from each other (their own initialisation and batches)
    w = [np.asarray(arrays(r.state.model)[0]) for r in together]
    assert not np.allclose(w[0], w[1])


def test_a_member_whose_guard_fires_leaves_the_group(tmp_path, data, monkeypatch):
    """Member 1's Adam stops at its step-8 record (its guard made to fire there): it keeps what it
    had then and goes to its polish; members 0 and 2 train on as a group of two (bootstrap
    members: their own window weights go with them) and end as they do alone."""
    config = CONFIG.replace(bootstrap=True)
    together = members(tmp_path / "together", data, config=config)
    watched = []
    real = trainer_module.stop_reason

    def stop_reason(history, config):
        if any(history is run.state.history for run in together[1:2]) and history[-1]["step"] == 8:
            watched.append(8)
            return "made to stop"
        return real(history, config)

    monkeypatch.setattr(trainer_module, "stop_reason", stop_reason)
    train_members(together, data)
    monkeypatch.setattr(trainer_module, "stop_reason", real)
    assert watched == [8]
    stopped = together[1].state
    assert stopped.stopped == "Adam stopped at step 8 of 24: made to stop"
    assert [r["step"] for r in stopped.history if "phase" not in r] == [8]
    assert stopped.history[-1]["phase"] == "lbfgs"  # polished after all
    alone = members(tmp_path / "alone", data, seeds=(0, 2), config=config)
    train_members(alone, data, together=False)
    assert_same_run(together[0], alone[0])
    assert_same_run(together[2], alone[1])


def test_what_cannot_run_together(tmp_path, data):
    """Members at different steps, with configurations that differ beyond the seed, or a single
    member, train one after another."""
    runs = members(tmp_path / "a", data, seeds=(0, 1))
    trainers = [r.trainer(data) for r in runs]
    states = [t.init(r.skeleton()) for r, t in zip(runs, trainers, strict=True)]
    assert can_run_together(trainers, states)
    assert not can_run_together(trainers[:1], states[:1])
    states[1].step = 3
    assert not can_run_together(trainers, states)
    states[1].step = 0
    other = members(tmp_path / "b", data, seeds=(1,), config=CONFIG.replace(lr=1e-3))[0]
    assert not can_run_together([trainers[0], other.trainer(data)], states)
    done = [t.init(r.skeleton()) for r, t in zip(runs, trainers, strict=True)]
    for state in done:
        state.step = CONFIG.steps  # Adam over
    assert not can_run_together(trainers, done)


def test_bootstrap_weights_weight_whole_trajectories():
    """Each window takes its trajectory's Bayesian-bootstrap weight: the same seed gives the same
    weights, another seed others; every weight is positive (no trajectory left out), they sum to
    n, and n times a flat Dirichlet draw is about exponential with mean 1 (here 2,000
    trajectories: the share below 1/2 is 1 − e^(−1/2) = 0.39, the variance (n − 1)/(n + 1))."""
    traj = np.repeat(np.arange(2000), 3)
    w = bootstrap_weights(traj, 2000, seed=4)
    np.testing.assert_array_equal(w, bootstrap_weights(traj, 2000, seed=4))
    assert not np.allclose(w, bootstrap_weights(traj, 2000, seed=5))
    weights = w.reshape(2000, 3)
    assert np.all(weights == weights[:, :1])  # one weight per trajectory
    assert weights.min() > 0
    np.testing.assert_allclose(weights[:, 0].sum(), 2000, rtol=1e-12)
    assert abs(np.mean(weights[:, 0] < 0.5) - (1 - np.exp(-0.5))) < 0.035
    assert abs(np.var(weights[:, 0]) - 1999 / 2001) < 0.1


def test_draw_batch_follows_the_weights():
    """Weighted draws: never a window of weight 0, frequencies in proportion to the weights
    (200,000 draws, 5 standard errors); unweighted draws are the uniform ones."""
    import jax

    weights = np.array([0.0, 1.0, 3.0, 0.0, 2.0, 2.0])
    idx = np.asarray(draw_batch(jax.random.PRNGKey(0), 6, 200_000, jnp.asarray(weights)))
    freq = np.bincount(idx, minlength=6) / idx.size
    p = weights / weights.sum()
    assert freq[0] == 0 and freq[3] == 0
    np.testing.assert_allclose(freq, p, atol=5 * np.sqrt(p.max() * (1 - p.max()) / idx.size))
    key = jax.random.PRNGKey(3)
    np.testing.assert_array_equal(draw_batch(key, 6, 50), jax.random.randint(key, (50,), 0, 6))


def test_quasi_newton_windows_of_a_bootstrap_member(data):
    """A bootstrap member's quasi-Newton phases draw as many windows as a plain member's (the
    compiled program's shape), from the same starts, with replacement in proportion to its
    trajectories' weights: repeats, and the trajectory of largest weight drawn more often per
    window than the one of smallest."""
    plain = Trainer(CONFIG, data.train, data.val)
    boot = Trainer(CONFIG.replace(bootstrap=True, seed=3), data.train, data.val)
    a, b = plain.quasi_newton_windows(), boot.quasi_newton_windows()
    assert len(a) == len(b) == min(CONFIG.lbfgs_pairs, len(plain.train_pairs))
    assert len(np.unique(a.start * 1000 + a.traj)) == len(a)  # plain: distinct windows
    assert len(np.unique(b.start * 1000 + b.traj)) < len(b)  # drawn with replacement
    pool = (boot.train_pairs.start - CONFIG.first_start) % CONFIG.lbfgs_stride == 0
    allowed = boot.train_pairs.start[pool] * 1000 + boot.train_pairs.traj[pool]
    assert set(b.start * 1000 + b.traj) <= set(allowed)  # the plain member's starts
    assert plain.window_weights is None
    traj, w = boot.train_pairs.traj, boot.window_weights
    per_traj = np.array([w[traj == k][0] for k in range(data.train.n_traj)])
    heavy, light = int(np.argmax(per_traj)), int(np.argmin(per_traj))
    share = [np.sum(b.traj == k) / np.sum(traj == k) for k in (heavy, light)]
    assert share[0] > share[1]


def test_an_ensemble_interval_holds_a_new_draw_nine_times_in_ten():
    """The interval of :func:`interval` from N members drawn from a normal law holds one more
    draw of that law (the truth, to a bagged estimate) with probability 0.90 (20,000 trials of
    N = 3 and of N = 5, ±1 %); the members' 5th–95th percentiles, the interval reported before,
    hold it about half the time for N = 3. NaN members give NaN."""
    rng = np.random.default_rng(0)
    for n in (3, 5):
        draws = rng.normal(2.0, 0.3, size=(n + 1, 20_000))
        median, lo, hi = interval(draws[:n])
        np.testing.assert_array_equal(median, np.median(draws[:n], axis=0))
        assert abs(np.mean((lo <= draws[n]) & (draws[n] <= hi)) - 0.90) < 0.01
    pct_lo, pct_hi = np.percentile(draws[:3], (5, 95), axis=0)
    assert 0.4 < np.mean((pct_lo <= draws[3]) & (draws[3] <= pct_hi)) < 0.5
    assert np.isnan(interval(np.array([[1.0], [np.nan], [2.0]]))[1][0])
    with pytest.raises(ValueError, match="at least 2 members"):
        interval(np.ones((1, 4)))
