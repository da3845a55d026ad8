"""An ensemble's Adam phases trained as one ``vmap``-ed program
(:func:`fhnn.training.trainer.run_together`): the same members as trained one after another, a
member whose guard fires leaves the group, and what cannot run together is recognised."""

from __future__ import annotations

import numpy as np
import pytest

import fhnn.training.ensemble as ensemble_module
import fhnn.training.trainer as trainer_module
from fhnn.models.fhnn import FHNNConfig
from fhnn.training.ensemble import train_members
from fhnn.training.run import Run, RunConfig
from fhnn.training.trainer import TrainConfig, can_run_together

from .conftest import arrays, small_dataset

CONFIG = TrainConfig(steps=24, val_every=8, batch_size=16, lbfgs_steps=3, lbfgs_pairs=64, lambda_flow=1e-6)


@pytest.fixture(scope="module")
def data():
    return small_dataset("steady_vortex", n_traj=4, duration=1.0)


def members(folder, ds, seeds=(0, 1, 2), config=CONFIG):
    folder.mkdir(exist_ok=True)
    return [
        Run.create(
            folder / f"seed-{s}", ds, RunConfig(model=FHNNConfig(width=8), train=config.replace(seed=s))
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


def test_members_trained_together_are_the_members_trained_alone(tmp_path, data, monkeypatch):
    """Three members' Adam phases as one program, each with the flow penalty (annealed) and the
    polish after: every record and the final weights are those of the members trained alone;
    each member's checkpoint on disk is its final state."""
    together = members(tmp_path / "together", data)
    alone = members(tmp_path / "alone", data)
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
    had then and goes to its polish; members 0 and 2 train on as a group of two and end as they
    do alone."""
    together = members(tmp_path / "together", data)
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
    alone = members(tmp_path / "alone", data, seeds=(0, 2))
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
