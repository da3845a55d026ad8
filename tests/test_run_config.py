"""Run configuration from the command line: dotted settings, settings files, plans, flags that
must agree, resuming only with the stored settings, and run folders found from anywhere."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
from pathlib import Path

import pytest

from fhnn.config import read_settings_file
from fhnn.data.dataset import read_dataset
from fhnn.errors import ConfigError
from fhnn.training.plans import (
    DEFAULT_PLAN,
    PAPER_FHNN,
    PAPER_TRAIN,
    PLANS,
    data_settings,
    default_settings,
    is_noisy,
)
from fhnn.training.run import RunConfig
from fhnn.training.train_config import WARMUP_ACCEPT

from .conftest import run_cli as cli


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--set", "model.widht=8"], "unknown setting 'model.widht' for run (did you mean 'model.width'?)"),
        (["--set", "width=8"], "unknown setting 'width' for run (did you mean 'model.width'?)"),
        (["--set", "train.lrr=1e-3"], "unknown setting 'train.lrr' for run (did you mean 'train.lr'?)"),
        (["--set", "train.lr=fast"], "training.lr must be a number, got 'fast'"),
        (["--seed", "3", "--set", "train.seed=5"], "--seed 3 and the setting train.seed=5 disagree"),
        (["--steps", "10", "--set", "train.steps=20"], "--steps 10 and the setting train.steps=20 disagree"),
        (["--model", "hnn", "--set", "kind=fhnn"], "--model hnn and the setting kind=fhnn disagree"),
        (["--model", "hnnn"], "unknown model 'hnnn' (did you mean 'hnn'?)"),
        (["--model", "hnn", "--ablation", "relu"], "--ablation applies to fhnn only, not 'hnn'"),
        (
            ["--plan", "fastest"],
            "unknown training plan 'fastest'; available: auto, adam, warmup-polish, adam-polish",
        ),
        (
            ["--config", "/nonexistent/settings.toml"],
            "settings file '/nonexistent/settings.toml' does not exist",
        ),
    ],
)
def test_bad_training_settings_are_one_line_exit_2_and_write_nothing(
    args: list[str], message: str, data_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    code, _, err = cli(["train", str(data_file), "-o", str(tmp_path / "run"), "-q", *args], capsys)
    assert code == 2
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert message in err
    assert list(tmp_path.iterdir()) == []


def test_settings_file_sections_and_flags_that_agree(tmp_path: Path) -> None:
    toml = tmp_path / "s.toml"
    toml.write_text('kind = "fhnn"\n[model]\nwidth = 8\n[train]\nlr = 1e-3\nlr_boundaries = [0.5]\n')
    assert read_settings_file(toml) == {
        "kind": "fhnn",
        "model.width": 8,
        "train.lr": 1e-3,
        "train.lr_boundaries": [0.5],
    }
    as_json = tmp_path / "s.json"
    as_json.write_text(json.dumps({"model": {"width": 8}, "train": {"lr": 1e-3, "lr_boundaries": [0.5]}}))
    a = RunConfig().with_settings(read_settings_file(toml))
    b = RunConfig().with_settings(read_settings_file(as_json))
    assert a == b and a.model.width == 8 and a.train.lr_boundaries == (0.5,)
    bad = tmp_path / "bad.toml"
    bad.write_text("[model\nwidth = 8\n")
    with pytest.raises(ConfigError, match=r"settings file '.*bad.toml' is not valid TOML"):
        read_settings_file(bad)
    (tmp_path / "s.yaml").write_text("model: {}")
    with pytest.raises(ConfigError, match="must end in .toml or .json"):
        read_settings_file(tmp_path / "s.yaml")


def test_plans_are_typed_training_configurations() -> None:
    # the defaults are the default plan; the paper's plan names every field it changes
    assert PLANS[DEFAULT_PLAN].train == RunConfig().train and PLANS[DEFAULT_PLAN].model == {}
    assert PLANS["adam"].settings("fhnn") == {
        **{f"train.{k}": v for k, v in PAPER_TRAIN.to_dict().items()},
        **{f"model.{k}": v for k, v in PAPER_FHNN.items()},
    }
    paper = RunConfig().with_settings(PLANS["adam"].settings("fhnn"))
    assert (paper.model.width, paper.model.slow_weight, paper.train.w_step, paper.train.lbfgs_steps) == (
        64,
        0.0,
        1.0,
        0,
    )
    solid = RunConfig().with_settings(PLANS["warmup-polish"].settings("fhnn"))
    assert (solid.train.steps, solid.train.warmup_steps, solid.train.lbfgs_steps) == (0, 400, 400)
    assert solid.model.width == 32  # the plan's FHNN width ...
    node = RunConfig(kind="node").with_settings(PLANS["warmup-polish"].settings("node"))
    assert node.model == RunConfig(kind="node").model  # ... is not a baseline's
    with pytest.raises(ConfigError, match="unknown model"):
        PLANS["adam"].settings("fnn")


def test_a_new_run_without_a_plan_starts_from_the_default_plan(
    data_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """No --plan: the default plan's settings (here with shortened phases given by --set, which
    win) and its width; the warm-up's decision is printed. Data with estimated velocities start
    from the training defaults instead (their multi-step settings come from the data)."""
    short = ["--set", "train.warmup_steps=5", "--set", "train.steps=4", "--set", "train.lbfgs_steps=2"]
    short += ["--set", "train.lbfgs_pairs=64", "--set", "train.val_every=2"]
    code, _, err = cli(["train", str(data_file), "-o", str(tmp_path / "run"), *short], capsys)
    assert code == 0, err
    info = json.loads((tmp_path / "run" / "run.json").read_text())
    assert info["train_config"]["warmup_accept"] == WARMUP_ACCEPT == PLANS[DEFAULT_PLAN].train.warmup_accept
    assert info["model_config"]["width"] == 32 and info["train_config"]["lbfgs_pairs"] == 64
    # a steady vortex is not a linear flow: the warm-up is given up at its first record
    warm = [r for r in info["history"] if r.get("phase") == "warmup"]
    assert [r["warmup"] for r in warm] == ["discarded"] and warm[0]["val_total"] > 1e4 * WARMUP_ACCEPT
    assert f"warm-up discarded at iteration {warm[0]['iteration']} of 5 (validation loss" in err
    assert info["step"] == 6 and [r["step"] for r in info["history"] if "phase" not in r] == [2, 4]
    ds = read_dataset(data_file)
    assert default_settings(ds) == PLANS[DEFAULT_PLAN].settings("fhnn")
    assert ds.obs_noise == 0 and info["model_config"]["slow_weight"] == 1.0  # noise-free: weighted
    assert "noise-free observations: each window weighted by its slowness (model.slow_weight=1)" in err
    # measured derivatives: the plan's derivative loss alone, no flow penalty
    assert info["train_config"]["w_step"] == 0.0 and info["train_config"]["lambda_flow"] == 0.0
    assert data_settings(ds) == {}
    # velocities measured, derivatives estimated: the one-step loss instead of the derivative loss
    ds.extra["measured"] = ["positions", "velocities", "forces"]
    assert data_settings(ds) == {"train.w_deriv": 0.0, "train.w_step": 1.0}
    config = RunConfig().with_settings({**default_settings(ds), **data_settings(ds)})
    assert (config.train.w_deriv, config.train.w_step, config.train.steps) == (0.0, 1.0, 20000)
    ds.extra["measured"] = ["positions"]  # velocities estimated (an imported table): the paper's start
    assert default_settings(ds) == PLANS["adam"].settings("fhnn")


def test_the_default_plan_weighs_slow_windows_on_noise_free_observations_only(data_file: Path) -> None:
    """The default plan's FHNN settings carry slow_weight 1 on noise-free observations and 0
    where the observations carry noise (simulated noise, or an imported table's estimate); the
    rest of the plan, and the baselines' settings, are the same for both."""
    plan, clean = PLANS[DEFAULT_PLAN], read_dataset(data_file)
    noisy = dataclasses.replace(clean, obs_noise=1e-3)
    assert not is_noisy(clean) and is_noisy(noisy)
    on, off = (RunConfig().with_settings({**default_settings(d), **data_settings(d)}) for d in (clean, noisy))
    assert (on.model.slow_weight, off.model.slow_weight) == (1.0, 0.0)
    assert on.model.replace(slow_weight=0.0) == off.model and on.train == off.train
    assert on.model.width == off.model.width == 32
    # the plan is the same on both; the data's noise changes the one field, in data_settings
    assert default_settings(noisy) == plan.settings("fhnn") == default_settings(clean)
    assert data_settings(noisy) == {"model.slow_weight": 0.0} and data_settings(clean) == {}
    for kind in ("node", "hnn"):  # no model settings of the rule's: the same on both
        assert data_settings(noisy, kind) == data_settings(clean, kind) == {}
    # every other plan leaves the windows unweighted, as the paper does
    assert {PLANS[name].settings("fhnn")["model.slow_weight"] for name in PLANS if name != DEFAULT_PLAN} == {
        0.0
    }


def test_resume_refuses_other_settings_and_runs_are_found_from_anywhere(
    data_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    project = tmp_path / "project"
    project.mkdir()
    shutil.copy(data_file, project / "d.h5")
    settings = project / "s.toml"
    settings.write_text("[model]\nwidth = 8\n[train]\nval_every = 2\n")
    monkeypatch.chdir(project)
    start = ["train", "d.h5", "-o", "run", "--plan", "adam", "--steps", "4", "--config", "s.toml", "-q"]
    code, _, err = cli(start, capsys)
    assert code == 0, err
    info = json.loads((project / "run" / "run.json").read_text())
    assert info["model_config"]["width"] == 8 and info["train_config"]["steps"] == 4
    assert info["data"] == "../d.h5" and len(info["data_sha256"]) == 64
    before = (project / "run" / "run.json").read_bytes()

    # the same command, or no options at all, resumes (here: nothing left to do)
    assert cli(start, capsys)[0] == 0
    assert cli(["train", "d.h5", "-o", "run", "-q"], capsys)[0] == 0
    # other settings are refused, naming them, and the run is untouched
    code, _, err = cli(["train", "d.h5", "-o", "run", "--set", "train.lr=1e-3", "--steps", "4", "-q"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert "run holds a run started with other settings (train.lr: 0.003 stored, 0.001 given)" in err
    code, _, err = cli(["train", "d.h5", "-o", "run", "--set", "model.width=16", "-q"], capsys)
    assert code == 2 and "model.width: 8 stored, 16 given" in err
    assert (project / "run" / "run.json").read_bytes() == before

    # evaluate and inspect from another working directory, then with run and data moved together
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    code, out, err = cli(["evaluate", str(project / "run"), "--horizons", "1,2", "--json"], capsys)
    assert code == 0, err
    first = json.loads(out)
    assert set(first) == {"1", "2", "diverged_count"}
    code, out, err = cli(["inspect", str(project / "run")], capsys)
    assert code == 0 and "flow: relative L2 error" in out, err
    moved = tmp_path / "moved"
    shutil.move(project, moved)
    code, out, _ = cli(["evaluate", str(moved / "run"), "--horizons", "1,2", "--json"], capsys)
    assert code == 0 and json.loads(out) == first

    # a changed data file is noticed; one that is gone is named
    (moved / "d.h5").write_bytes((moved / "d.h5").read_bytes() + b"\0")
    code, _, err = cli(["evaluate", str(moved / "run"), "--horizons", "1"], capsys)
    assert code == 2 and "the data set changed since the run" in err and "SHA-256 differs" in err
    os.remove(moved / "d.h5")
    code, _, err = cli(["evaluate", str(moved / "run"), "--horizons", "1"], capsys)
    assert code == 2 and "its data set '../d.h5' is not where the run recorded it" in err
