"""What a new user meets first: default horizons, file modes, output paths, checkpoint errors,
interrupting and resuming training, finished runs and --extend."""

from __future__ import annotations

import itertools
import json
import os
import stat
from pathlib import Path

import pytest

from fhnn.cli.app import main
from fhnn.data.dataset import write_dataset
from fhnn.errors import DataFormatError
from fhnn.training.run import Run

from .conftest import paper_fhnn, paper_train, small_dataset
from .conftest import run_cli as cli


@pytest.fixture(scope="module")
def trained(data_file: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("runs") / "run"
    with pytest.raises(SystemExit) as info:
        main(
            [
                "train",
                str(data_file),
                "-o",
                str(out),
                "--plan",
                "adam",
                "--steps",
                "6",
                "--set",
                "model.width=8",
                "-q",
            ]
        )
    assert info.value.code == 0
    return out


def test_evaluate_defaults_to_the_horizons_the_test_set_allows_and_fits_80_columns(
    trained: Path, capsys: pytest.CaptureFixture
) -> None:
    code, out, err = cli(["evaluate", str(trained)], capsys)
    assert code == 0, err
    assert "horizons 1, 2 s: the test trajectories last 3 s (--horizons chooses others)" in err
    rows = [line.split()[0] for line in out.splitlines() if line.strip()[:1].isdigit()]
    assert rows == ["1", "2"]
    assert "…" not in out and max(len(line) for line in out.splitlines()) <= 80
    assert "RMSE" in out and "diverged" in out
    code, _, err = cli(["evaluate", str(trained), "--split", "training"], capsys)
    assert code == 2 and "--split must be one of train, val, test, got 'training'" in err


def test_finished_runs_say_so_and_extend_needs_more_steps(
    trained: Path, data_file: Path, capsys: pytest.CaptureFixture
) -> None:
    code, out, _ = cli(["train", str(data_file), "-o", str(trained), "-q"], capsys)
    assert (
        code == 0 and "has finished training (Adam 6 of 6 steps); nothing to do" in out and "--extend" in out
    )
    code, _, err = cli(["train", str(data_file), "-o", str(trained), "--extend", "-q"], capsys)
    assert code == 2 and "--extend continues" in err and "give --steps larger than its 6" in err
    code, _, err = cli(["train", str(data_file), "-o", str(trained), "--steps", "8", "-q"], capsys)
    assert code == 2 and "train.steps: 6 stored, 8 given" in err
    code, out, err = cli(["train", str(data_file), "-o", str(trained), "--steps", "8", "--extend"], capsys)
    assert code == 0, err
    assert json.loads((trained / "run.json").read_text())["step"] == 8
    code, _, err = cli(["train", str(data_file), "-o", str(trained.parent / "new"), "--extend", "-q"], capsys)
    assert code == 2 and "holds none" in err


def test_written_files_get_the_usual_mode_under_the_umask(
    trained: Path, data_file: Path, tmp_path: Path
) -> None:
    old = os.umask(0o022)
    try:
        path = write_dataset(
            small_dataset("steady_vortex", n_traj=3, duration=0.2, test_duration=0.2), tmp_path / "a.h5"
        )
        run = Run.load(trained)
        run.folder = tmp_path / "copy"
        run.save()
    finally:
        os.umask(old)
    for p in (path, *(run.folder.iterdir())):
        assert stat.S_IMODE(p.stat().st_mode) == 0o644, p


def test_output_paths_that_cannot_be_written_are_named_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch, data_file: Path
) -> None:
    (tmp_path / "somefile.h5").write_text("mine")
    code, _, err = cli(["simulate", "steady_vortex", "-o", str(tmp_path / "somefile.h5" / "out.h5")], capsys)
    assert code == 2 and err == f"error: output folder '{tmp_path / 'somefile.h5'}' is a file, not a folder\n"
    locked = tmp_path / "locked"
    locked.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == locked else real_access(p, mode))
    code, _, err = cli(["simulate", "steady_vortex", "-o", str(locked / "out.h5")], capsys)
    assert code == 2 and err == f"error: output folder '{locked}' is not writable\n"
    code, _, err = cli(["train", str(data_file), "-o", str(locked / "run")], capsys)
    assert code == 2 and err == f"error: output folder '{locked}' is not writable\n"
    assert list(locked.iterdir()) == []
    code, _, err = cli(["simulate", "steady_vortex", "-o", str(tmp_path / "x.h5"), "-p", "gamma"], capsys)
    assert code == 2 and "--param expects NAME=VALUE" in err
    code, _, err = cli(["train", str(data_file), "-o", str(tmp_path / "r"), "--set", "train.lr"], capsys)
    assert code == 2 and "--set expects NAME=VALUE, got 'train.lr'" in err


def test_a_corrupt_checkpoint_file_is_named(trained: Path, tmp_path: Path) -> None:
    import shutil

    copy = tmp_path / "run"
    shutil.copytree(trained, copy)
    (copy / "best.eqx").write_bytes((copy / "best.eqx").read_bytes()[:40])
    with pytest.raises(
        DataFormatError, match=rf"^{copy / 'best.eqx'}: checkpoint files missing or incompatible"
    ):
        Run.load(copy)
    (copy / "best.eqx").unlink()
    with pytest.raises(
        DataFormatError, match=r"best.eqx: checkpoint files missing or incompatible \(no such file\)"
    ):
        Run.load(copy)


# --- the force models see is the recorded force -----------------------------------------------------


def test_rollouts_and_losses_use_the_recorded_forces() -> None:
    """A data set whose forcing exists only as recorded samples (no actuation parameters): a probe
    model ṡ = (v, F/m) rolled out from rest must follow the interpolated force exactly."""
    import jax.numpy as jnp
    import numpy as np

    from fhnn.data.dataset import Split
    from fhnn.data.windows import LossScales, Windows
    from fhnn.models.base import AbstractVectorField
    from fhnn.physics.actuation import no_actuation

    mass = 2.0

    class Probe(AbstractVectorField):
        def __call__(self, state, t, force):
            return jnp.concatenate([state[2:], force / mass])

    t = np.linspace(0.0, 3.0, 31)
    a, b = 0.4, -0.3  # F_x = a + b t, F_y = 0.5 a: linear, so the interpolant is exact
    forces = np.zeros((2, t.size, 2))
    forces[0, :, 0] = a + b * t
    forces[0, :, 1] = 0.5 * a
    states = np.zeros((2, t.size, 4))
    split = Split(
        t=t, states=states, states_clean=states, derivs=states, forces=forces, actuation=no_actuation(2)
    )
    np.testing.assert_array_equal(split.force_residual, forces)
    ro = Probe().rollout(split)
    x = (a * t**2 / 2 + b * t**3 / 6) / mass  # hand-integrated from rest
    np.testing.assert_allclose(ro.states[0, :, 0], x, atol=1e-12)
    np.testing.assert_allclose(ro.states[0, :, 1], 0.25 * a * t**2 / mass, atol=1e-12)
    np.testing.assert_allclose(ro.states[0, :, 2], (a * t + b * t**2 / 2) / mass, atol=1e-12)
    assert np.all(ro.states[1] == 0.0)  # the unforced trajectory stays at rest
    # the derivative loss sees the recorded force at each window's first sample
    windows = Windows.of(split)
    batch = windows.as_jax()
    deriv = np.zeros_like(windows.deriv)
    deriv[:, 0, 2:] = windows.forces[:, 0] / mass
    batch["deriv"] = jnp.asarray(deriv)
    sc = LossScales.of(windows)
    terms = Probe().loss_terms(batch, (jnp.ones(4), jnp.asarray(sc.step)))
    assert float(terms["deriv"]) < 1e-28


def test_a_file_whose_forces_disagree_with_its_actuation_is_refused(tmp_path: Path) -> None:
    import h5py

    from fhnn.data.dataset import read_dataset

    data = small_dataset("steady_vortex", n_traj=4, duration=1.0, test_duration=1.0)
    path = write_dataset(data, tmp_path / "d.h5")
    assert read_dataset(path).train.force_residual.max() == 0.0  # simulated: the sinusoids exactly
    with h5py.File(path, "r+") as f:
        f["train/forces"][1, 3, 0] += 0.01
    with pytest.raises(
        DataFormatError,
        match=r"/train/forces disagree with /actuation for 1 trajectory\(ies\), first trajectory 1 at t = 0.15 s",
    ):
        read_dataset(path)


def test_version_scenario_units_and_the_near_initial_note(
    trained: Path, capsys: pytest.CaptureFixture
) -> None:
    from fhnn import __version__

    code, out, _ = cli(["--version"], capsys)
    assert code == 0 and out == f"fhnn {__version__}\n"
    code, out, _ = cli(["scenarios"], capsys)
    assert code == 0
    assert "default data set: 100 trajectories split 70/20/10 %, train/val 20 s, test 120 s" in out
    assert "gamma" in out and "m²/s" in out and "N·s/m" in out
    code, out, _ = cli(["inspect", str(trained)], capsys)  # 6 steps: the coefficients barely moved
    assert code == 0 and "still lie within 5 % of their initial values" in out and "--extend" in out
    code, out, _ = cli(["inspect", str(trained), "--json"], capsys)
    near = json.loads(out)["coefficients"]["_near_initial"]
    assert near and set(near) <= {"m_ax", "m_ay", "c_q", "c_l"}
    for name in ("flow.png", "coefficients.png"):
        assert (trained / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_progress_is_told_after_every_step_of_each_phase(data_file: Path) -> None:
    """Every quasi-Newton step is told, and every chunk of Adam steps (one compiled call of at most
    ``ADAM_CHUNK`` steps, ending at each validation and at each multiple of ``ADAM_CHUNK``): the
    fault tests' kills land there; the CLI throttles its bar."""
    from fhnn.data.dataset import read_dataset
    from fhnn.models.registry import MODELS
    from fhnn.training.trainer import ADAM_CHUNK, Trainer

    ds = read_dataset(data_file)
    told: list[tuple[str, int]] = []
    steps = 2 * ADAM_CHUNK + 20
    config = paper_train(
        steps=steps, val_every=ADAM_CHUNK + 30, warmup_steps=2, lbfgs_steps=2, lbfgs_pairs=50, batch_size=8
    )
    trainer = Trainer(config, ds.train, ds.val, on_step=lambda phase, step: told.append((phase, step)))
    model = MODELS["fhnn"].make(paper_fhnn(width=8), MODELS["fhnn"].arguments(ds), 0)
    state = trainer.polish(trainer.run(trainer.warmup(trainer.init(model))))
    assert state.step == steps + 2
    adam = [step for phase, step in told if phase == "adam"]
    assert told[:2] == [("warmup", 0), ("warmup", 0)] and told[-2:] == [
        ("lbfgs", steps + 1),
        ("lbfgs", steps + 2),
    ]
    assert told[2:-2] == [("adam", step) for step in adam]
    # strictly increasing, no chunk longer than ADAM_CHUNK, every validation and multiple of it told
    assert all(0 < b - a <= ADAM_CHUNK for a, b in itertools.pairwise([0, *adam]))
    assert {ADAM_CHUNK, ADAM_CHUNK + 30, 2 * ADAM_CHUNK, steps} <= set(adam) and adam[-1] == steps
    assert [r["step"] for r in state.history if r.get("phase") is None] == [ADAM_CHUNK + 30, steps]
