"""`fhnn reproduce`: the job grid, caching, tables, the report, Ray, interruption and resumption."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fhnn.errors import ConfigError, FhnnError
from fhnn.experiments.executors import FAST_COMPILE_FLAGS, Task, _start_worker, run_local
from fhnn.experiments.grid import HORIZONS, ReproduceConfig, build_grid
from fhnn.experiments.reproduce import check_output_folder, reproduce
from fhnn.experiments.tables import DIVERGENCE_RULE, build_tables, layout, to_csv, to_json, to_markdown

from .conftest import PAPER_TRAIN, paper_train
from .report_checks import check_report

ROOT = Path(__file__).resolve().parents[1]

# --- the grid --------------------------------------------------------------------------------


def test_default_grid_covers_every_table_without_repeats() -> None:
    config = ReproduceConfig()
    datasets, jobs = build_grid(config)
    labels = [j.label for j in jobs]
    assert len(labels) == len(set(labels))
    # 2 main scenarios × (7 models + 5 ablations) + 4 other T4 scenarios + steady without actuation
    assert len(jobs) == config.seeds * (2 * 12 + 4 + 1)
    assert sorted(d.label for d in datasets) == sorted(
        [
            "solid_body_vortex",
            "steady_vortex",
            "time_varying_vortex",
            "noisy_flow",
            "obstacle",
            "wave",
            "steady_vortex_noact",
        ]
    )
    assert {j.seed for j in jobs} == {0, 1, 2}


def test_every_job_trains_with_the_default_plan_under_one_budget() -> None:
    """The reproduction trains as ``fhnn train`` does (the default plan's phases, loss terms and
    polish, its FHNN width, also for the ablations) with fewer Adam steps, fewer quasi-Newton pairs
    and a wall-clock budget per job."""
    from fhnn.experiments.grid import JOB_ADAM_STEPS, JOB_LBFGS_PAIRS, JOB_SECONDS
    from fhnn.training.plans import DEFAULT_PLAN, PLANS

    config, plan = ReproduceConfig(), PLANS[DEFAULT_PLAN]
    assert config.train.max_time == JOB_SECONDS > 0 and config.train.steps == JOB_ADAM_STEPS
    assert 0 < JOB_ADAM_STEPS < plan.train.steps and config.train.lbfgs_steps == plan.train.lbfgs_steps > 0
    assert 0 < JOB_LBFGS_PAIRS == config.train.lbfgs_pairs < plan.train.lbfgs_pairs
    same = {"steps": plan.train.steps, "max_time": plan.train.max_time, "lbfgs_pairs": plan.train.lbfgs_pairs}
    assert config.train.replace(**same) == plan.train
    # the default plan's FHNN is the configuration defaults (width 32, slow-window weights)
    assert plan.model == {} and config.model.fhnn == type(config.model.fhnn)()
    assert (config.model.fhnn.width, config.model.fhnn.slow_weight) == (32, 1.0)
    fhnn_jobs = [j for j in build_grid(config)[1] if j.model == "fhnn"]
    assert {j.run.model.width for j in fhnn_jobs} == {32}
    # the plan's slow-window weights on noise-free observations, none on noisy_flow's
    weights = {(j.data.scenario, j.run.model.slow_weight) for j in fhnn_jobs}
    assert {w for sc, w in weights if sc != "noisy_flow"} == {1.0}
    assert {w for sc, w in weights if sc == "noisy_flow"} == {0.0}
    assert {j.data.noisy for j in fhnn_jobs} == {True, False}
    assert {j.run.train.replace(seed=0) for j in build_grid(config)[1]} == {config.train}


def test_job_ids_change_with_what_determines_the_result_only() -> None:
    _, a = build_grid(ReproduceConfig(seeds=1))
    _, b = build_grid(ReproduceConfig(seeds=1))
    _, c = build_grid(ReproduceConfig(seeds=1, train=paper_train(steps=1501)))
    _, d = build_grid(ReproduceConfig(seeds=2, models=("fhnn",)))
    assert [j.id for j in a] == [j.id for j in b]
    assert not {j.id for j in a} & {j.id for j in c}
    # a seed-0 FHNN job is the same job whatever else the grid holds
    assert {j.id for j in d if j.seed == 0 and j.variant == "fhnn"} <= {j.id for j in a}
    # compiled for compilation speed the results differ in their last bits: other data, other jobs
    data_fast, fast = build_grid(ReproduceConfig(seeds=1, fast_compile=True))
    assert not {j.id for j in a} & {j.id for j in fast}
    assert not {d.id for d in build_grid(ReproduceConfig(seeds=1))[0]} & {d.id for d in data_fast}
    assert ReproduceConfig.quick().fast_compile and not ReproduceConfig().fast_compile
    # seeds trained together differ in their last bits: other jobs, on the same data sets
    data_together, together = build_grid(ReproduceConfig(seeds=2, models=("fhnn",), seeds_together=True))
    assert all(j.together and j.spec["together"] for j in together)
    assert not {j.id for j in d} & {j.id for j in together}
    assert [x.id for x in data_together] == [
        x.id for x in build_grid(ReproduceConfig(seeds=2, models=("fhnn",)))[0]
    ]
    # one seed has no cell to share: the setting changes nothing
    assert [j.id for j in build_grid(ReproduceConfig(seeds=1, seeds_together=True))[1]] == [j.id for j in a]


def test_a_worker_adds_its_xla_flags_before_compiling(monkeypatch) -> None:
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_enable_fast_math=false")
    _start_worker(None, FAST_COMPILE_FLAGS)
    assert os.environ["XLA_FLAGS"] == f"--xla_cpu_enable_fast_math=false {FAST_COMPILE_FLAGS}"
    monkeypatch.delenv("XLA_FLAGS")
    _start_worker(None, "")
    assert "XLA_FLAGS" not in os.environ


def test_job_ids_change_with_the_code_each_job_runs_and_nothing_else(tmp_path: Path, monkeypatch) -> None:
    """A copy of the package's source: editing a model file reruns the model jobs and keeps the
    data sets; editing the physics reruns both; editing the CLI or the report reruns nothing."""
    import functools

    import fhnn.experiments.grid as grid
    from fhnn.runtime import PACKAGE_ROOT, source_digest

    root = tmp_path / "fhnn"
    shutil.copytree(PACKAGE_ROOT, root, ignore=shutil.ignore_patterns("__pycache__"))
    config = ReproduceConfig(seeds=1, models=("fhnn",), ablations=(), scenario_table=())

    def ids() -> tuple[set[str], set[str]]:
        source_digest.cache_clear()
        monkeypatch.setattr(grid, "source_digest", functools.partial(source_digest, root=root))
        data, models = build_grid(config)
        return {d.id for d in data}, {j.id for j in models}

    before = ids()
    for edited, data_changes, models_change in (
        ("cli/app.py", False, False),
        ("experiments/report.py", False, False),
        ("models/fhnn.py", False, True),
        ("physics/flows.py", True, True),
    ):
        with (root / edited).open("a") as f:
            f.write("\n_EDITED = 1\n")  # code: the digest ignores comments and docstrings
        after = ids()
        assert (after[0] != before[0]) == data_changes, edited
        assert (after[1] != before[1]) == models_change, edited
        assert after[0] & before[0] == (set() if data_changes else before[0])
        before = after


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"models": ("fhnn", "gpt")}, "unknown name 'gpt' in models"),
        ({"ablations": ("no_flow", "no_flow")}, "lists a name twice"),
        ({"main_scenarios": ("vortex",)}, "unknown name 'vortex' in main_scenarios"),
        ({"data": {"test_duration": 60.0}}, "test_duration must cover the longest horizon"),
        ({"seeds": 0}, "seeds"),
        ({"data": {"n_traj": 2}}, "n_traj must be >= 3"),
        ({"data": {"dt": -0.1}}, "dt must be > 0"),
        ({"sedes": 2}, "did you mean 'seeds'"),
    ],
)
def test_bad_reproduce_configuration_is_refused(changes: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(message)):
        ReproduceConfig.from_dict(changes)


def test_output_folder_that_holds_something_else_is_refused(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="not empty and holds no reproduction"):
        check_output_folder(tmp_path)
    with pytest.raises(ConfigError, match="does not exist"):
        check_output_folder(tmp_path / "missing" / "out")
    check_output_folder(tmp_path / "new")  # a new folder is fine


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--set", "models=gpt"], "error: reproduce: unknown name 'gpt' in models"),
        (["--seeds", "0"], "error: reproduce: seeds must be > 0, got 0"),
        (["--workers", "0"], "error: --workers must be >= 1, got 0"),
        (["--set", "seeds"], "error: --set expects NAME=VALUE"),
        (
            ["--set", "trian.steps=3"],
            "error: unknown setting 'trian.steps' for reproduce (did you mean 'train.steps'?)",
        ),
        (["--set", "steps=3"], "error: unknown setting 'steps' for reproduce (did you mean 'train.steps'?)"),
        (
            ["--set", "model.fhnn.widht=3"],
            "error: unknown setting 'model.fhnn.widht' for reproduce (did you mean 'model.fhnn.width'?)",
        ),
        (["--set", "train.seed=2"], "error: reproduce: train.seed is set per job"),
        (
            ["--steps", "10", "--set", "train.steps=20"],
            "error: --steps 10 and the setting train.steps=20 disagree",
        ),
        (
            ["--set", "data.test_duration=30"],
            "error: reproduce: test_duration must cover the longest horizon",
        ),
    ],
)
def test_reproduce_cli_bad_input_is_one_line_exit_2_and_writes_nothing(
    args: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    from fhnn.cli.app import main

    out = tmp_path / "out"
    with pytest.raises(SystemExit) as info:
        main(["reproduce", "-o", str(out), "-q", *args])
    err = capsys.readouterr().err
    assert info.value.code == 2
    assert err.startswith(message) and err.count("\n") == 1
    assert not out.exists()


def test_reproduce_cli_refuses_a_folder_holding_other_things(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    from fhnn.cli.app import main

    (tmp_path / "thesis.tex").write_text("keep me")
    with pytest.raises(SystemExit) as info:
        main(["reproduce", "--quick", "-o", str(tmp_path), "-q"])
    assert info.value.code == 2
    assert "holds no reproduction" in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["thesis.tex"]


# --- tables from hand-made results ---------------------------------------------------------------


def _result(value: float, diverged: int = 0, n: int = 4, recovery: float | None = None) -> dict:
    def metrics(v: float) -> dict:
        return {
            str(h): {
                "rmse_pos": v * h,
                "rmse_vel": v,
                "ade": v,
                "fde": v,
                "within_eps": 0.5,
                "outside_training": 0.25,
                "diverged": diverged,
                "n_traj": n,
            }
            for h in HORIZONS
        }

    out = {"spec_metrics": metrics(value), "paper_metrics": metrics(value / 2)}
    if recovery is not None:
        out["recovery"] = {
            "coefficients": {k: {"max_rel": recovery} for k in ("m_ax", "m_ay", "c_q", "c_l")},
            "flow": {"rel_l2": recovery / 10},
        }
    return out


def test_cells_are_mean_and_sample_std_over_seeds_with_the_paper_beside() -> None:
    config = ReproduceConfig(
        seeds=2,
        models=("fhnn", "lnn"),
        ablations=(),
        main_scenarios=("solid_body_vortex",),
        scenario_table=(),
    )
    _, jobs = build_grid(config.replace(identifiability=False))
    results = {}
    for j in jobs:
        if j.model == "fhnn":
            results[j.id] = _result(1e-3 if j.seed == 0 else 3e-3, recovery=0.02 * (j.seed + 1))
        else:  # the LNN: seed 0 diverged everywhere, seed 1 in one of four rollouts
            results[j.id] = _result(math.nan, diverged=4) if j.seed == 0 else _result(0.5, diverged=1)
    cells = build_tables(jobs, results, ("solid_body_vortex",), ())
    cell = next(c for c in cells if (c.table, c.model, c.horizon, c.metric) == ("T2", "fhnn", 5, "rmse_pos"))
    assert cell.mean == pytest.approx(1e-2)  # (5e-3 + 15e-3) / 2
    assert cell.std == pytest.approx(np.std([5e-3, 15e-3], ddof=1))
    assert cell.mean_paper_avg == pytest.approx(5e-3)
    assert cell.paper == 6.09e-4
    assert cell.text() == "1.00e-02 ± 7.07e-03"
    lnn = next(c for c in cells if (c.table, c.model, c.horizon, c.metric) == ("T2", "lnn", 5, "rmse_pos"))
    # no survivor averages: both seeds had a diverged rollout, so both count as infinite
    assert lnn.mean == math.inf and lnn.diverged == 5 and lnn.rollouts == 8
    assert lnn.statistic == "median" and lnn.text() == "diverged (5/8)"
    assert lnn.paper == 5.85e10
    t6 = next(c for c in cells if (c.table, c.metric) == ("T6", "m_ax"))
    assert t6.mean == pytest.approx(0.03) and t6.text().startswith("3 % ±")
    # T1 compares FHNN with the Neural ODE only: no Neural ODE ran, so only FHNN rows
    assert {c.model for c in cells if c.table == "T1"} == {"fhnn"}
    rows = json.loads(to_json(cells, {"commit": "abc"}))["cells"]
    assert len(rows) == len(cells) and all(r["mean"] is None or math.isfinite(r["mean"]) for r in rows)
    assert to_csv(cells).count("\n") == len(cells) + 1
    for _, _, header, table_rows in layout(cells):
        assert all(len(r) == len(header) for r in table_rows)


def test_a_seed_with_a_diverged_rollout_is_kept_as_infinite_and_the_cell_shows_the_median() -> None:
    config = ReproduceConfig(
        seeds=3,
        models=("fhnn",),
        ablations=(),
        main_scenarios=("solid_body_vortex",),
        scenario_table=(),
        identifiability=False,
    )
    _, jobs = build_grid(config)
    value = {0: 1e-3, 1: 2e-3, 2: 0.7}  # seed 2 diverged in one rollout: its 0.7 is a survivor mean
    results = {j.id: _result(value[j.seed], diverged=int(j.seed == 2)) for j in jobs}
    cells = build_tables(jobs, results, ("solid_body_vortex",), ())
    cell = next(c for c in cells if (c.table, c.horizon, c.metric) == ("T2", 1, "rmse_pos"))
    assert cell.statistic == "median" and cell.mean == pytest.approx(2e-3)  # median of (1e-3, 2e-3, inf)
    assert math.isnan(cell.std)
    assert cell.text() == "median 2.00e-03 (1/12 div.)"
    outside = next(c for c in cells if (c.table, c.horizon, c.metric) == ("T3", 30, "outside_training"))
    assert outside.mean == pytest.approx(0.25) and outside.statistic == "mean"  # a fraction stays finite
    markdown = to_markdown(cells, 3)
    assert markdown.count(DIVERGENCE_RULE) == 1 + len({(k, t) for k, t, _, _ in layout(cells) if k != "T6"})


def test_t6_counts_seeds_whose_recovery_is_not_finite_and_prints_any_spread() -> None:
    """T6 leaves a non-finite seed out of the mean and says so; a small spread is printed as
    it is, never rounded to '± 0 %'."""
    config = ReproduceConfig(
        seeds=3,
        models=("fhnn",),
        ablations=(),
        main_scenarios=("solid_body_vortex",),
        scenario_table=(),
        identifiability=False,
    )
    _, jobs = build_grid(config)
    value = {0: 3e-6, 1: 1e-6, 2: math.nan}
    results = {j.id: _result(1e-3, recovery=value[j.seed]) for j in jobs}
    cell = next(c for c in build_tables(jobs, results, ("solid_body_vortex",), ()) if c.metric == "m_ax")
    assert (cell.diverged, cell.rollouts, cell.seeds) == (1, 3, 2)
    assert cell.mean == pytest.approx(2e-6) and cell.std == pytest.approx(np.std([3e-6, 1e-6], ddof=1))
    assert cell.text() == "0.0002 % ± 0.00014 % (1/3 seeds non-finite, left out)"


def test_the_grid_trains_as_fhnn_train_does_on_data_without_known_forcing() -> None:
    """The reproduction applies the model settings ``fhnn train`` applies (constant added
    masses where they are a gauge of the data, no slow-window weights on noisy data)."""
    from fhnn.data.simulate import SimulationConfig, simulate_dataset
    from fhnn.physics.scenarios import get_scenario
    from fhnn.training.plans import data_settings

    config = ReproduceConfig(models=("fhnn",), ablations=(), seeds=1)
    datasets, jobs = build_grid(config)
    for d in datasets:
        sc = get_scenario(d.scenario)
        small = simulate_dataset(
            sc, SimulationConfig.for_scenario(sc, **{**d.settings, "n_traj": 3, "duration": 1.0})
        )
        (job,) = [j for j in jobs if j.data.id == d.id]
        implied = {
            k.removeprefix("model."): v for k, v in data_settings(small).items() if k.startswith("model.")
        }
        assert job.run.model == config.model.fhnn.replace(**implied), d.label
    assert {d.label for d in datasets if d.masses_are_gauge} == {"solid_body_vortex", "steady_vortex_noact"}


def test_a_cell_whose_every_rollout_diverged_reads_diverged() -> None:
    config = ReproduceConfig(
        seeds=1,
        models=("lnn",),
        ablations=(),
        main_scenarios=("solid_body_vortex",),
        scenario_table=(),
        identifiability=False,
    )
    _, jobs = build_grid(config)
    cells = build_tables(jobs, {jobs[0].id: _result(math.nan, diverged=4)}, ("solid_body_vortex",), ())
    assert {c.text() for c in cells if c.metric == "rmse_pos"} == {"diverged (4/4)"}


# --- executors ---------------------------------------------------------------------------------


def test_a_failing_job_is_reported_by_name_after_the_others_finish(tmp_path: Path) -> None:
    done = []
    bad = Task("bad-job", "data", ({"scenario": "steady_vortex", "settings": {"n_traj": 1}},))
    good = Task(
        "good-job",
        "data",
        ({"scenario": "steady_vortex", "settings": {"n_traj": 3, "duration": 0.2, "test_duration": 0.2}},),
    )
    with pytest.raises(FhnnError, match=r"1 job\(s\) failed \(bad-job: ConfigError: .*n_traj"):
        run_local([bad, good], lambda t, out: done.append(t.name), workers=1)
    assert done == ["good-job"]


# --- end to end --------------------------------------------------------------------------------

TWO_JOBS = {
    "seeds": 1,
    "train": {**PAPER_TRAIN.to_dict(), "steps": 30, "val_every": 30},  # no warm-up, no polish
    "data": {"n_traj": 6, "duration": 1.0, "dt": 0.1},
    "models": ("fhnn", "node"),
    "ablations": (),
    "main_scenarios": ("steady_vortex",),
    "scenario_table": (),
    "identifiability": False,
}


def _metrics(out: Path) -> dict[str, dict]:
    return {
        p.parent.name: json.loads(p.read_text())["spec_metrics"]
        for p in sorted((out / "jobs").glob("*/result.json"))
    }


def test_seeds_together_train_each_cell_as_one_task_with_the_numbers_of_separate_jobs(tmp_path: Path) -> None:
    """``seeds_together``: a cell's two seeds are one task (one progress report naming both), each
    job still its own folder; a member lost is retrained alone, and nothing else, to the numbers it
    had trained together but for the last bits of the vmapped sums (the lone job trains as a
    reproduction without ``seeds_together`` does: its specification differs in that flag only)."""
    settings = {**TWO_JOBS, "seeds": 2, "models": ("fhnn",)}
    reports: list[str] = []
    config = ReproduceConfig.from_dict({**settings, "seeds_together": True})
    together = reproduce(config, tmp_path / "together", workers=1, progress=lambda *a: reports.append(a[3]))
    assert together.jobs_run == 2
    assert "steady_vortex__fhnn__s0 + steady_vortex__fhnn__s1" in reports
    b = {r["spec"]["seed"]: r for r in map(json.loads, _results(tmp_path / "together"))}
    assert sorted(b) == [0, 1]
    for seed in (0, 1):
        assert b[seed]["trained_with"] == 2 and b[seed]["spec"]["together"] and b[seed]["steps"] == 30
    assert b[0]["best_val"] != b[1]["best_val"]  # the seeds are different models
    lost = next(p for p in (tmp_path / "together" / "jobs").iterdir() if "__s1-" in p.name)
    shutil.rmtree(lost)
    again = reproduce(config, tmp_path / "together", workers=1)
    assert again.jobs_run == 1
    alone = json.loads((lost / "result.json").read_text())
    assert "trained_with" not in alone and alone["steps"] == 30
    assert alone["best_val"] == pytest.approx(b[1]["best_val"], rel=1e-10)
    assert alone["spec_metrics"]["5"]["rmse_pos"] == pytest.approx(
        b[1]["spec_metrics"]["5"]["rmse_pos"], rel=1e-10
    )
    # a job of a reproduction without seeds_together is the same job but for that flag
    apart = [j.spec for j in build_grid(ReproduceConfig.from_dict(settings))[1]]
    assert [{k: v for k, v in j.spec.items() if k != "together"} for j in build_grid(config)[1]] == apart


def _results(out: Path) -> list[str]:
    return [p.read_text() for p in sorted((out / "jobs").glob("*/result.json"))]


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:os.fork")
def test_ray_cluster_gives_the_numbers_of_the_local_executor(tmp_path: Path) -> None:
    """An FHNN job on a one-CPU Ray cluster gives the bytes of the same job in a local worker.
    Both compile with ``fast_compile``'s XLA flags (local workers set them as they start, Ray
    starts its workers with them): a worker without them would differ in the last bits. Left out
    of the default run (45 s of a worker in a 2-core suite): ``benchmarks/quick_reproduction.py
    --ray`` makes the same check on every job of ``fhnn reproduce --quick``
    (``benchmarks/results/quick_reproduction_ray.json``)."""
    ray = pytest.importorskip("ray")
    config = ReproduceConfig.from_dict({**TWO_JOBS, "models": ("fhnn",), "fast_compile": True})
    local = reproduce(config, tmp_path / "local", workers=1)  # one worker process, for the flags
    assert local.jobs_run == 1
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        remote = reproduce(config, tmp_path / "ray", ray_address="auto")
    finally:
        ray.shutdown()
    assert remote.jobs_run == 1
    a, b = _metrics(tmp_path / "local"), _metrics(tmp_path / "ray")
    assert list(a) == list(b) and len(a) == 1
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)  # bit-identical


def _fhnn(*args: str) -> list[str]:
    return [sys.executable, "-c", "from fhnn.cli.app import main; main()", *args]


def _reproduce_twice(out: Path) -> None:
    """Run ``fhnn reproduce --quick`` into ``out`` (its jobs in one process: ``--workers 1``; in
    the suite the other test worker already keeps the second core busy), then again, which must
    run nothing and keep the report."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    run = subprocess.run(
        _fhnn("reproduce", "--quick", "-o", str(out), "-q", "--workers", "1"),
        env=env,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    n_data, n_jobs = (len(x) for x in build_grid(ReproduceConfig.quick()))
    assert f"{n_data} of {n_data} data sets and {n_jobs} of {n_jobs} training jobs run" in run.stdout
    again = subprocess.run(
        _fhnn("reproduce", "--quick", "-o", str(out), "-q"),
        env=env,
        capture_output=True,
        text=True,
    )
    assert again.returncode == 0, again.stderr
    assert (
        f"0 of {n_data} data sets and 0 of" in again.stdout and "nothing changed, report kept" in again.stdout
    )


@pytest.mark.slow
def test_quick_reproduction_runs_every_table_and_renders(tmp_path: Path) -> None:
    """The README's main job as it is, all five scenarios in T4, every check of its report
    (tests/report_checks.py), then again, which must run nothing and keep the report. Left out
    of the default run (133 s of a worker in a 2-core suite): ``benchmarks/quick_reproduction.py``
    runs the same command cold, warm and as a rerun and makes the same checks on both reports
    (``benchmarks/results/quick_reproduction.json``); kills and resumes of a reproduction:
    tests/test_faults.py."""
    _reproduce_twice(tmp_path / "report")
    check_report(
        tmp_path / "report",
        tmp_path,
        {"steady_vortex", "time_varying_vortex", "noisy_flow", "obstacle", "wave"},
    )
