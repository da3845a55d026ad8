"""What ends or skips a training phase: the warm-up's route decision (``train.warmup_accept``)
and the time budget (``train.max_time``)."""

from __future__ import annotations

import re
import time
from dataclasses import replace

import numpy as np
import pytest

from fhnn.errors import ConfigError
from fhnn.models.baselines import MLPConfig
from fhnn.training.budget import Budget
from fhnn.training.run import Run, RunConfig
from fhnn.training.trainer import Trainer

from .conftest import arrays, paper_fhnn, paper_train, small_dataset


def test_the_warmup_is_kept_or_discarded_by_its_validation_loss(tmp_path):
    """``train.warmup_accept``: a warm-up whose validation loss is at or below it is kept and Adam
    is skipped (the polish follows); one above it is discarded — Adam starts from the initial
    model, as if there had been no warm-up. Checked on both sides of the measured loss."""
    ds = small_dataset("solid_body_vortex", n_traj=8, duration=2.0)

    def run(folder, accept):
        config = paper_train(
            steps=6, val_every=4, batch_size=16, warmup_steps=20, warmup_accept=accept, lbfgs_pairs=1500
        )
        return Run.create(tmp_path / folder, ds, RunConfig(model=paper_fhnn(width=16), train=config))

    kept = run("kept", 1.0)
    state = kept.train(ds, save=False)
    warm = state.history[-1]
    assert warm["phase"] == "warmup" and warm["warmup"] == "kept" and len(state.history) == 5
    assert state.step == 6 and kept.finished  # no Adam record: Adam was skipped
    assert state.best_val == warm["val_total"] < 1.0

    discarded = run("discarded", warm["val_total"] * 0.999)
    initial = discarded.skeleton()
    state = discarded.train(ds, save=False, until=0)
    assert state.history[-1]["warmup"] == "discarded" and state.best_val == np.inf
    for a, b in zip(arrays(state.model), arrays(initial), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    state = discarded.train(ds, save=False)  # Adam, from the initial model
    assert [r["step"] for r in state.history if "phase" not in r] == [4, 6]
    # a warm-up 1e4 times above the threshold at a record is given up there
    hopeless = run("hopeless", warm["val_total"] * 1e-4 / 1.001).train(ds, save=False, until=0)
    assert [(r["iteration"], r.get("warmup")) for r in hopeless.history] == [(4, "discarded")]
    with pytest.raises(ConfigError, match="warmup_accept"):
        paper_train(warmup_accept=-1.0)


def test_the_time_budget_ends_each_phase_and_says_so_and_the_next_command_continues(tmp_path):
    """``train.max_time``: with the budget spent, Adam stops at its next step (the phases before a
    polish get half the budget), the polish at its next iteration; ``stopped`` names both cuts and
    the summary says what ran. The run is not finished: loaded again (a new command, a new
    budget) it continues Adam from its step and then polishes, to the same number of steps as a
    run that was never cut. Without a budget nothing is cut."""
    ds = small_dataset("steady_vortex", n_traj=4, duration=1.0)
    config = paper_train(steps=50, val_every=10, batch_size=16, lbfgs_steps=5, lbfgs_pairs=64, max_time=1e-9)
    run = Run.create(
        tmp_path / "r", ds, RunConfig(kind="node", model=MLPConfig(width=8, depth=1), train=config)
    )
    state = run.train(ds)
    assert re.fullmatch(
        r"Adam stopped at step 1 of 50: the time budget \(train.max_time=1e-09 s, 50% of it before the "
        r"polish\) ran out after \d+ s; the L-BFGS polish stopped at iteration 1 of 5: the time budget "
        r"\(train.max_time=1e-09 s\) ran out after \d+ s",
        state.stopped,
    ), state.stopped
    assert [(r["step"], r.get("phase"), r.get("budget")) for r in state.history] == [
        (1, None, True),
        (51, "lbfgs", True),
    ]
    assert run.ran() == "Adam 1 of 50 steps, L-BFGS polish 1 of 5 iterations"
    again = Run.load(tmp_path / "r")
    assert not again.finished and again.state.stopped == state.stopped
    again.config = again.config.with_settings({"train.max_time": 0.0})
    assert again.continue_cut() == "continues the Adam from step 1 of 50, where the time budget cut it"
    assert again.state.step == 1 and again.state.stopped is None
    state = again.train(ds, save=False)
    adam = [r["step"] for r in state.history if "phase" not in r]
    assert adam == [1, 10, 20, 30, 40, 50] and state.step == 55 and again.finished
    assert again.ran() == "Adam 50 of 50 steps, L-BFGS polish 5 of 5 iterations" and state.stopped is None
    assert again.continue_cut() is None  # the cuts are continued once
    free = Run.create(
        tmp_path / "f",
        ds,
        RunConfig(kind="node", model=MLPConfig(width=8, depth=1), train=replace(config, max_time=0.0)),
    )
    state = free.train(ds, save=False)
    assert state.stopped is None and [r["step"] for r in state.history][-1] == 55


def test_a_polish_cut_by_the_budget_continues_with_its_iterations_left(tmp_path):
    """A polish cut at iteration k continues, in the next command, from the best model with the
    ``lbfgs_steps − k`` iterations left, numbered on from k."""
    ds = small_dataset("steady_vortex", n_traj=4, duration=1.0)
    config = paper_train(steps=4, val_every=2, batch_size=16, lbfgs_steps=6, lbfgs_pairs=64)
    run = Run.create(
        tmp_path / "r", ds, RunConfig(kind="node", model=MLPConfig(width=8, depth=1), train=config)
    )
    state = run.train(ds, save=False, budget=Budget(1e-9, final_phases=True, start=time.monotonic() + 1e6))
    # an infinite-looking budget for Adam (its start in the future), then spent for the polish
    trainer = run.trainer(ds, budget=Budget(1e-9, final_phases=True))
    state.step = 4
    state.history = [r for r in state.history if "phase" not in r]
    run.finish(trainer, save=False)
    assert [(r["step"], r.get("iteration"), r.get("budget")) for r in state.history][-1] == (5, 1, True)
    assert run.ran() == "Adam 4 of 4 steps, L-BFGS polish 1 of 6 iterations" and not run.finished
    assert (
        run.continue_cut()
        == "continues the L-BFGS polish from iteration 1 of 6, where the time budget cut it"
    )
    state = run.train(ds, save=False, budget=Budget(0.0, final_phases=True))
    polish = [(r["step"], r["iteration"]) for r in state.history if r.get("phase") == "lbfgs"]
    assert polish[1:] == [(6, 2), (7, 3), (8, 4), (9, 5), (10, 6)] and run.finished


def test_a_discarded_warmup_leaves_adam_and_the_polish_what_is_left(tmp_path):
    """The time of a discarded warm-up is sunk: Adam and the polish split what is left of the
    budget in the usual shares (half before the polish), counted from the discard; a kept warm-up
    changes nothing. The budget started 800 s ago of 1,000 s."""
    ds = small_dataset("solid_body_vortex", n_traj=4, duration=1.0)
    model = Run.create(
        tmp_path / "run", ds, RunConfig(model=paper_fhnn(width=8), train=paper_train())
    ).skeleton()

    def trainer(accept):
        config = paper_train(
            warmup_steps=2, warmup_accept=accept, lbfgs_steps=5, lbfgs_pairs=64, max_time=1000.0
        )
        t = Trainer(config, ds.train, ds.val, budget=Budget.of(config, start=time.monotonic() - 800.0))

        def quasi_newton(state, *args, **kwargs):  # the warm-up's iterations: one record at loss 1
            state.history.append({"phase": "warmup", "iteration": 2, "val_total": 1.0})
            return state

        t._quasi_newton = quasi_newton
        return t

    t = trainer(0.5)  # the warm-up's loss 1 is above it: discarded
    assert t.warmup(t.init(model)).history[-1]["warmup"] == "discarded"
    left = t.budget.end - time.monotonic()  # ~200 s
    assert 0.5 * left - 1.0 < t.deadline("adam") - time.monotonic() <= 0.5 * left + 0.5
    assert t.deadline("lbfgs") == t.deadline("tracks") == t.budget.start + 1000.0
    kept = trainer(2.0)
    assert kept.warmup(kept.init(model)).history[-1]["warmup"] == "kept"
    start = kept.budget.start
    assert kept.deadline("adam") == start + 500.0 and kept.deadline("lbfgs") == start + 1000.0


def test_an_earlier_phase_cut_does_not_end_adam(tmp_path):
    """A run whose warm-up the budget cut in an earlier process resumes with a new budget: its
    stored ``stopped`` text must not end Adam at its first validation (only a cut of this phase
    does), so Adam runs to its end and the polish follows."""
    ds = small_dataset("steady_vortex", n_traj=4, duration=1.0)
    config = paper_train(steps=4, val_every=2, batch_size=16)
    run = Run.create(
        tmp_path / "r", ds, RunConfig(kind="node", model=MLPConfig(width=8, depth=1), train=config)
    )
    earlier = (
        "the warm-up stopped at iteration 3 of 8: the time budget (train.max_time=9 s) ran out after 5 s"
    )
    run.state = Trainer(config, ds.train, ds.val).init(run.skeleton())
    run.state.stopped = earlier
    state = run.train(ds, save=False)
    assert [r["step"] for r in state.history] == [2, 4] and state.step == 4 and run.finished
    assert state.stopped == earlier


def test_the_validation_total_weighs_terms_as_training_does(tmp_path):
    """The best model is chosen by the validation loss the training minimises: a term trained with
    weight 0 (the derivative loss on data whose derivatives were estimated) is reported but left
    out of ``total``, and the others enter with their weights."""
    ds = small_dataset("solid_body_vortex", n_traj=4, duration=1.0)
    model = Run.create(
        tmp_path / "run", ds, RunConfig(model=paper_fhnn(width=8), train=paper_train())
    ).skeleton()
    both = Trainer(paper_train(), ds.train, ds.val).validate(model)
    assert both["total"] == pytest.approx(both["deriv"] + both["step"], rel=1e-12)
    weighted = Trainer(paper_train(w_deriv=0.0, w_step=2.5), ds.train, ds.val).validate(model)
    assert weighted["deriv"] == both["deriv"] > 0
    assert weighted["total"] == pytest.approx(2.5 * both["step"], rel=1e-12)


def test_compilation_counts_and_members_one_after_another_share_what_is_left():
    """The budget runs from the command's start whatever the programs cost to compile (the
    deadlines do not move when a program is first called); members that run a phase one after
    another each get an equal share of what is left (:meth:`Budget.turn`), and members that train
    wholly one after another a budget of their own of that share (:meth:`Budget.share`)."""
    ds = small_dataset("steady_vortex", n_traj=4, duration=1.0)
    t = Trainer(paper_train(max_time=100.0, lbfgs_steps=5), ds.train, ds.val)
    adam, lbfgs = t.deadline("adam"), t.deadline("lbfgs")
    assert lbfgs - adam == pytest.approx(50.0)
    assert t._program("sleep", time.sleep, 0.2) is None
    assert (t.deadline("adam"), t.deadline("lbfgs")) == (adam, lbfgs)
    budget = Budget(90.0, final_phases=True)
    with budget.turn("lbfgs", 3):
        assert budget.deadline("lbfgs") - time.monotonic() == pytest.approx(30.0, abs=0.5)
        assert "this member's share of it" in budget.describe("lbfgs")
    assert budget.deadline("lbfgs") == budget.end
    with budget.turn("adam", 3):  # a third of the 45 s before the polish
        assert budget.deadline("adam") - time.monotonic() == pytest.approx(15.0, abs=0.5)
    own = budget.share(3)
    assert own.seconds == pytest.approx(30.0, abs=0.5) and own.first_end - own.start == pytest.approx(
        own.seconds / 2
    )
    assert own.describe("adam") == (
        "train.max_time=90 s, this member's share of it, 50% of it before the polish"
    )
    assert Budget(0.0, final_phases=True).deadline("adam") == np.inf


def test_a_whole_track_fit_that_would_not_end_in_time_is_not_begun_and_continues_later(tmp_path):
    """With the budget spent before the whole-track fit, no iteration starts (one would end past
    the budget): a record at iteration 0 marks the cut, the summary says 0 iterations ran, and the
    next command continues the fit from its first iteration."""
    ds = small_dataset("steady_vortex", n_traj=4, duration=1.0)
    config = paper_train(steps=2, val_every=2, batch_size=16, track_steps=2)
    run = Run.create(tmp_path / "r", ds, RunConfig(model=paper_fhnn(width=8), train=config))
    trainer = run.trainer(ds, budget=Budget(0.0, final_phases=True))
    run.begin(trainer, save=False)
    run.adam(trainer, save=False)
    run.finish(run.trainer(ds, budget=Budget(1e-9, final_phases=True)), save=False)
    last = run.state.history[-1]
    assert (last["phase"], last["iteration"], last["budget"], last["step"]) == ("tracks", 0, True, 2)
    assert "before iteration 1 of 2: the time budget" in run.state.stopped and not run.finished
    assert run.ran() == "Adam 2 of 2 steps, whole-track fit 0 of 2 iterations"
    assert (
        run.continue_cut()
        == "continues the whole-track fit from iteration 0 of 2, where the time budget cut it"
    )
    state = run.train(ds, save=False, budget=Budget(0.0, final_phases=True))
    assert [r["iteration"] for r in state.history if r.get("phase") == "tracks"][1:] == [
        1,
        2,
    ] and run.finished
