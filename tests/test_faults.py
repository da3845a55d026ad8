"""Faults: processes killed (SIGKILL) or interrupted (SIGINT) in every phase of simulate, train and
reproduce resume to the bytes of an uninterrupted run and never leave a half-written file; a full
disk keeps the previous checkpoint; guards stop runs that cannot improve; two reproductions never
write into one folder at once.

Kills are placed with the CLI's test hook ``FHNN_FAULT_AT=PHASE:N:SIGNAL`` (the command sends
itself SIGNAL once its progress reaches N in PHASE), so each lands in the phase it names."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import equinox as eqx
import numpy as np
import pytest

import fhnn.training.adam as adam_module
import fhnn.training.trainer as trainer_module
from fhnn.cli.app import FAULT_ENV, main
from fhnn.data.dataset import write_dataset
from fhnn.errors import ConfigError, DataFormatError
from fhnn.files import commit_files, folder_lock, recover_files
from fhnn.training.run import Run
from fhnn.training.trainer import stop_reason

from .conftest import PAPER_RUN, paper_train, small_dataset
from .fault_checks import ended_as, fhnn_command, leftovers, reproduction_files


def _env(fault: str | None = None) -> dict[str, str]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "FHNN_CHECKPOINT_SECONDS": "0.2"}
    env.pop(FAULT_ENV, None)
    if fault:
        env[FAULT_ENV] = fault
    return env


def _cli(*args: str, fault: str | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(fhnn_command(*args), env=_env(fault), capture_output=True, text=True, timeout=600)


def _expect_killed(proc: subprocess.CompletedProcess[str], sig: str) -> None:
    """A SIGKILL ends the process at once (status −9); a SIGINT is caught: one line, status 130."""
    assert ended_as(proc, sig), (proc.returncode, proc.stderr)


# --- the checkpoint journal ------------------------------------------------------------------------


class _Killed(BaseException):
    """Stands for a kill: raised in the middle of a write, it skips every ``except Exception``."""


@pytest.mark.parametrize("kill_at", range(8))
def test_a_commit_killed_at_any_rename_leaves_all_old_or_all_new_files(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, kill_at: int
) -> None:
    names = ("model.eqx", "best.eqx", "run.json")
    for name in names:
        (tmp_path / name).write_text(f"old {name}")
    real_replace, calls = os.replace, []

    def replace(src: str | os.PathLike[str], dst: str | os.PathLike[str]) -> None:
        calls.append(dst)
        if len(calls) > kill_at:
            raise _Killed
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    writers = {n: (lambda tmp, n=n: Path(tmp).write_text(f"new {n}")) for n in names}
    try:
        commit_files(tmp_path, writers)
        killed = False
    except _Killed:
        killed = True
    monkeypatch.setattr(os, "replace", real_replace)
    recover_files(tmp_path)  # what loading the run does
    contents = {(tmp_path / n).read_text().split()[0] for n in names}
    # 3 pending files + the journal are written before the commit point, 3 renames after it
    assert contents == ({"old"} if kill_at < 4 else {"new"}), (kill_at, contents)
    assert killed == (kill_at < 7)
    assert leftovers(tmp_path) == []


def test_a_full_disk_keeps_the_previous_checkpoint(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    dataset = small_dataset("solid_body_vortex", n_traj=4, duration=1.0, test_duration=2.0)
    run = Run.create(tmp_path / "run", dataset, PAPER_RUN.with_settings({"model.width": 8}))
    run.state = trainer_module.Trainer(run.train_config, dataset.train, dataset.val).init(run.skeleton())
    run.save()
    before = {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()}
    real = eqx.tree_serialise_leaves

    def full_disk(path, tree):
        if "best" in str(path):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(path, tree)

    monkeypatch.setattr(eqx, "tree_serialise_leaves", full_disk)
    run.state.step, run.state.best_val = 40, 1.0
    with pytest.raises(DataFormatError, match=r"cannot write '.*/run/best\.eqx': No space left on device"):
        run.save()
    after = {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()}
    assert after == before  # nothing new, nothing lost, no temporary file left
    assert Run.load(tmp_path / "run").state.step == 0


# --- training guards --------------------------------------------------------------------------------


def _history(vals: list[float], skipped: list[float] | None = None, every: int = 10) -> list[dict]:
    skipped = skipped or [0.0] * len(vals)
    return [
        {"step": every * (i + 1), "val_total": v, "skipped_steps": s}
        for i, (v, s) in enumerate(zip(vals, skipped, strict=True))
    ]


def test_stop_reasons_name_what_happened() -> None:
    config = paper_train(stop_rising=6)
    assert stop_reason(_history([5, 4, 3, 4, 5, 6, 7, 8]), config) is None  # five rises
    assert stop_reason(_history([5, 4, 3, 4, 5, 6, 7, 8, 9]), config) == (
        "the validation loss rose at 6 validations in a row (steps 30–90)"
    )
    assert stop_reason(_history([5, 4, 3, 4, 5, 6, 7, 8, 9]), paper_train(stop_rising=0)) is None
    assert stop_reason(_history([3, 2], [0.0, 10.0]), config) == (
        "every Adam step from 10 to 20 was skipped (non-finite loss or gradient)"
    )
    assert stop_reason(_history([3, 2], [0.0, 9.0]), config) is None
    warm = [{"step": 0, "phase": "warmup", "val_total": 1.0}]
    assert stop_reason(warm, config) is None


@pytest.mark.parametrize("fault", ["nan", "rising"])
def test_a_guard_stops_training_keeps_the_best_model_and_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture, fault: str
) -> None:
    data = write_dataset(
        small_dataset("solid_body_vortex", n_traj=4, duration=1.0, test_duration=2.0), tmp_path / "d.h5"
    )
    vals = iter(np.arange(1.0, 100.0))

    def chunk(model, opt_state, i, n, *rest):
        return model, opt_state, {"loss": np.nan, "deriv": np.nan, "skipped": float(fault == "nan") * n}

    monkeypatch.setattr(adam_module, "adam_chunk", chunk)
    monkeypatch.setattr(
        trainer_module.Trainer,
        "validate",
        lambda self, model: {"deriv": 0.0, "step": 0.0, "total": next(vals)},
    )
    args = [
        "train",
        str(data),
        "-o",
        str(tmp_path / "run"),
        "--plan",
        "adam",
        "--steps",
        "1000",
        "--set",
        "train.val_every=10",
    ]
    with pytest.raises(SystemExit) as info:
        main([*args, "--set", "model.width=8", "-q"])
    assert info.value.code == 0
    stopped_at, why = (
        (10, "every Adam step from 0 to 10 was skipped (non-finite loss or gradient)")
        if fault == "nan"
        else (70, "the validation loss rose at 6 validations in a row (steps 10–70)")
    )
    err = capsys.readouterr().err
    why = f"Adam stopped at step {stopped_at} of 1000: {why}"
    assert err == f"{why}; the result is the best model (validation loss 1.000e+00, step 10)\n"
    saved = json.loads((tmp_path / "run" / "run.json").read_text())
    assert saved["stopped"] == why and saved["best_val"] == 1.0
    assert saved["step"] == 1000 and saved["history"][-1]["step"] == stopped_at  # Adam is over
    with pytest.raises(SystemExit) as info:  # the same command again: finished, said once more
        main([*args, "--set", "model.width=8", "-q"])
    assert info.value.code == 0
    out, err = capsys.readouterr()
    assert why in err and "has finished training" in out


# --- kills with real processes ----------------------------------------------------------------------

#: A small plan with all three phases: warm-up, Adam, polish.
TRAIN = ["--plan", "adam", "--steps", "400", "--set", "model.width=8", "--set", "train.val_every=200", "-q"]
TRAIN += ["--set", "train.warmup_steps=8", "--set", "train.lbfgs_steps=8", "--set", "train.lbfgs_pairs=400"]


@pytest.fixture(scope="module")
def straight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A data set and the run of ``TRAIN`` on it, uninterrupted (``straight/run``)."""
    folder = tmp_path_factory.mktemp("straight")
    data = write_dataset(
        small_dataset("steady_vortex", n_traj=6, duration=2.0, test_duration=3.0), folder / "d.h5"
    )
    with pytest.raises(SystemExit) as info:
        main(["train", str(data), "-o", str(folder / "run"), *TRAIN])
    assert info.value.code == 0
    return folder


def test_training_killed_in_every_phase_resumes_to_the_same_bytes(straight: Path) -> None:
    """One run killed five times — in the warm-up, in Adam before its first validation (SIGINT,
    then SIGKILL, both after a timed checkpoint), after a validation, in the polish — and resumed
    after each kill, ends with the files of the uninterrupted run."""
    out, data = straight / "killed", str(straight / "d.h5")
    steps = []
    for fault in ("warmup:0:KILL", "adam:15:INT", "adam:30:KILL", "adam:250:KILL", "lbfgs:401:KILL"):
        killed = _cli("train", data, "-o", str(out), *TRAIN, fault=fault)
        _expect_killed(killed, fault.rsplit(":", 1)[1])
        info = json.loads((out / "run.json").read_text()) if (out / "run.json").exists() else {"step": None}
        steps.append(info["step"])
        if fault == "adam:15:INT":
            assert f"interrupted: {out} keeps the checkpoint of step {info['step']}" in killed.stderr
    # nothing saved in the warm-up; timed checkpoints before the first validation (step 200); the
    # checkpoint at the end of Adam survives a kill in the polish
    assert steps[0] is None and 0 < steps[1] < 200 and steps[1] <= steps[2] < 200, steps
    assert 200 <= steps[3] < 400 and steps[4] == 400, steps
    resumed = _cli("train", data, "-o", str(out), *TRAIN)
    assert resumed.returncode == 0, resumed.stderr
    assert leftovers(out) == []
    for name in ("model.eqx", "best.eqx", "opt_state.eqx", "run.json"):
        assert (out / name).read_bytes() == (straight / "run" / name).read_bytes(), name


def test_simulate_killed_keeps_the_previous_file_and_reruns_to_the_same_bytes(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    args = ["simulate", "steady_vortex", "--n-traj", "6", "--duration", "2", "--test-duration", "3", "-q"]
    for seed, name in ((5, "straight.h5"), (4, "d.h5")):  # an uninterrupted run; the user's old file
        with pytest.raises(SystemExit) as info:
            main([*args, "--seed", str(seed), "-o", str(tmp_path / name)])
        assert info.value.code == 0
    target = tmp_path / "d.h5"
    previous = target.read_bytes()
    for fault in ("train+val:1:KILL", "train+val:1:INT", "test:1:KILL"):
        killed = _cli(*args, "--seed", "5", "-o", str(target), fault=fault)
        _expect_killed(killed, fault.rsplit(":", 1)[1])
        assert target.read_bytes() == previous
        assert sorted(p.name for p in tmp_path.iterdir()) == ["d.h5", "straight.h5"]
    assert _cli(*args, "--seed", "5", "-o", str(target)).returncode == 0
    assert target.read_bytes() == (tmp_path / "straight.h5").read_bytes()


#: A reproduction small enough for the tests: one data set, FHNN with two seeds, its report.
REPRODUCE = ["reproduce", "--quick", "--seeds", "2", "-q", "--set", "models=fhnn"]
REPRODUCE += ["--set", "ablations=[]", "--set", "scenario_table=[]", "--set", "data.test_duration=120"]
REPRODUCE += ["--set", "data.n_traj=8", "--set", "train.steps=40", "--set", "train.val_every=20"]


@pytest.mark.slow
def test_reproduction_killed_three_times_resumes_to_the_bytes_of_a_two_worker_run(tmp_path: Path) -> None:
    """A second reproduction on a running one's folder is refused; one killed after a job (SIGKILL,
    SIGINT) and in its report resumes to the bytes of an uninterrupted two-worker run. Left out of
    the default run (69 s of a worker in a 2-core suite near its 900 s budget):
    ``benchmarks/reproduction_faults.py`` makes the same checks on ``fhnn reproduce --quick``
    (``benchmarks/results/reproduction_faults.json``)."""
    straight = tmp_path / "straight"
    proc = subprocess.Popen(
        fhnn_command(*REPRODUCE, "-o", str(straight), "--workers", "2"),
        env=_env(),
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not (straight / "reproduce.json").exists():
        assert proc.poll() is None, proc.stderr.read()
        time.sleep(0.05)
    # a second reproduction on the same folder is refused while the first runs, and changes nothing
    second = _cli(*REPRODUCE, "-o", str(straight))
    assert second.returncode == 2
    assert f"error: '{straight}' is in use by another fhnn reproduce (process {proc.pid})" in second.stderr
    _, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 0, stderr

    out = tmp_path / "killed"
    # after the data set, after the first model job, before the report (each run resumes the last)
    for fault in ("jobs:1:KILL", "jobs:1:INT", "report:0:KILL"):
        _expect_killed(
            _cli(*REPRODUCE, "-o", str(out), "--workers", "1", fault=fault), fault.rsplit(":", 1)[1]
        )
    final = _cli(*REPRODUCE, "-o", str(out), "--workers", "1")
    assert final.returncode == 0, final.stderr
    assert "0 of 1 data sets and 0 of 2 training jobs run, report rebuilt" in final.stdout
    assert leftovers(out) == []
    a, b = reproduction_files(straight), reproduction_files(out)
    assert sorted(a) == sorted(b) and len(a) > 10
    for name in a:
        assert a[name] == b[name], name


def test_a_held_folder_lock_refuses_a_second_holder_and_names_the_first(tmp_path: Path) -> None:
    with folder_lock(tmp_path, "fhnn reproduce"):
        child = subprocess.run(
            [
                sys.executable,
                "-c",
                f"from fhnn.files import folder_lock\nwith folder_lock({str(tmp_path)!r}, 'x'): pass",
            ],
            capture_output=True,
            text=True,
        )
        assert f"is in use by another x (process {os.getpid()})" in child.stderr
    with folder_lock(tmp_path, "fhnn reproduce"):  # released at the end of the block
        pass
    with pytest.raises(ConfigError):
        with folder_lock(tmp_path, "a"), folder_lock(tmp_path, "b"):
            pass
