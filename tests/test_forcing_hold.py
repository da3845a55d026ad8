"""A forcing table of thrusters that switch at its rows' times (``--forcing-hold previous``) is
held between rows and changes exactly at them: in ``fhnn predict``'s forecast, and in an imported
data set, which keeps each interval's change time for training and evaluation."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest

import fhnn
from fhnn.data.conversion import forcing_at_samples
from fhnn.data.dataset import Dataset, Split, read_dataset, write_dataset
from fhnn.data.simulate import integrate_held
from fhnn.data.table import held
from fhnn.data.windows import Windows
from fhnn.errors import ConfigError, DataFormatError
from fhnn.evaluation.predict import predict_tracks
from fhnn.models.registry import MODELS
from fhnn.physics.actuation import forcing, held_grid
from fhnn.physics.integrators import rk4_solve, rk4_solve_held
from fhnn.training.run import RunConfig

from .conftest import run_cli, small_dataset

START = np.array([0.8, 0.4, 0.05, -0.1])
F0, F1, F2 = np.array([0.4, 0.0]), np.array([-0.3, 0.5]), np.array([0.1, -0.2])


def _model():
    kind = MODELS["fhnn"]
    return kind.make(RunConfig().model, kind.arguments(small_dataset("steady_vortex")), 0)


def _constant(model, start, t0, duration, force) -> np.ndarray:
    """The state after ``duration`` s under a constant ``force``."""
    rows = {None: (np.array([t0, t0 + duration]), np.stack([force, force]))}
    got = predict_tracks(model, duration=duration, dt=duration / 50, initial=start, t0=t0, forcing_table=rows)
    return got.states[0, -1]


def test_a_held_forcing_table_switches_exactly_at_its_rows() -> None:
    model = _model()
    rows = {None: (np.array([0.0, 0.73, 1.46, 3.0]), np.stack([F0, F1, F2, F2]))}
    # the reference: three forecasts under constant forces, each from where the last one ended
    mid = _constant(model, START, 0.0, 0.73, F0)
    mid = _constant(model, mid, 0.73, 0.73, F1)
    want = _constant(model, mid, 1.46, 0.54, F2)
    step = predict_tracks(model, duration=2.0, dt=0.1, initial=START, forcing_table=held(rows, "previous"))
    assert step.t[0, -1] == pytest.approx(2.0)
    np.testing.assert_allclose(step.states[0, -1], want, atol=1e-7)
    ramp = predict_tracks(model, duration=2.0, dt=0.1, initial=START, forcing_table=held(rows, "linear"))
    assert np.max(np.abs(ramp.states[0, -1, :2] - want[:2])) > 100 * np.max(
        np.abs(step.states[0, -1, :2] - want[:2])
    )


def test_held_rows_are_a_step_and_a_bad_hold_is_refused() -> None:
    rows = {"a": (np.array([0.0, 2.0, 4.0]), np.stack([F0, F1, F2]))}
    t, f = held(rows, "previous")["a"]
    np.testing.assert_allclose(np.interp([1.0, 1.999, 2.0, 3.5], t, f[:, 0]), [F0[0], F0[0], F1[0], F1[0]])
    assert held(rows, "linear") is rows
    with pytest.raises(ConfigError, match="--forcing-hold must be one of linear, previous, got 'step'"):
        held(rows, "step")


# --- held forcing in training and evaluation: a data set that keeps each interval's change time


def test_rk4_held_is_exact_for_a_force_held_between_changes() -> None:
    """A double integrator under a held force: RK4 is exact for each constant-force part, so
    the split steps give the exact path; one step over a change (the interpolated force) does not."""
    ts = jnp.linspace(0.0, 1.0, 6)
    u = jnp.array([1.0, 1.0, -2.0, -2.0, 0.5, 0.5])
    switch = jnp.array([0.2, 0.33, 0.6, 0.71, 1.0, 1.0])  # changes inside intervals 1 and 3
    field = lambda s, t, f: jnp.array([s[1], f])  # noqa: E731
    held = np.asarray(rk4_solve_held(field, jnp.zeros(2), ts, u, switch))

    def exact(t: float) -> float:
        x, v, at = 0.0, 0.0, 0.0
        for change, force in ((0.33, 1.0), (0.71, -2.0), (np.inf, 0.5)):
            dt = min(t, change) - at
            if dt <= 0:
                break
            x, v, at = x + v * dt + 0.5 * force * dt**2, v + force * dt, at + dt
        return x

    want = np.array([exact(float(t)) for t in ts])
    np.testing.assert_allclose(held[:, 0], want, atol=1e-14)
    interpolated = np.asarray(rk4_solve(lambda s, t: field(s, t, jnp.interp(t, ts, u)), jnp.zeros(2), ts))
    assert np.max(np.abs(interpolated[:, 0] - want)) > 1e-3


def test_held_grid_is_the_step_function_at_the_solver_knots() -> None:
    t = np.array([[0.0, 0.1, 0.2, 0.3]])
    force = np.array([[[1.0, 0.0], [2.0, 0.0], [2.0, 0.0], [3.0, 1.0]]])
    switch = np.array([[0.04, 0.2, 0.3, 0.3]])  # a change inside interval 0; at samples after
    grid, values, picks = held_grid(t, force, switch)
    np.testing.assert_array_equal(grid[0, picks[0]], t[0])
    probe = [0.0, 0.039, 0.04, 0.15, 0.2, 0.29, 0.3]
    np.testing.assert_allclose(np.interp(probe, grid[0], values[0, :, 0]), [1, 1, 2, 2, 2, 2, 3], atol=1e-4)


def test_forcing_at_samples_keeps_one_change_per_interval() -> None:
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    rows = (np.array([-1.0, 0.13, 0.3, 0.35]), np.array([[1.0, 0], [2.0, 0], [3.0, 0], [3.0, 0]]))
    forces, switch = forcing_at_samples(t, rows, "previous", "a")
    np.testing.assert_array_equal(forces[:, 0], [1, 1, 2, 3, 3])
    # interval 1 changes at 0.13; interval 2's change is at its end sample; 0.35 repeats a force
    np.testing.assert_array_equal(switch, [0.1, 0.13, 0.3, 0.4, 0.4])
    with pytest.raises(DataFormatError, match="ends at 0.35 s, before the last sample of trajectory 'a'"):
        forcing_at_samples(t, rows, "linear", "a")


def _held_tracks(n: int = 3, duration: float = 4.0) -> tuple[Dataset, list, np.ndarray, np.ndarray]:
    """Tracks of steady_vortex's true body under thrust held between changes that fall between
    samples: ``(data set, forcing rows per track, fine times, fine states)``."""
    data = small_dataset("steady_vortex")
    fine = np.arange(0.0, duration + 1e-9, 0.01)
    rng = np.random.default_rng(5)
    rows = [(np.array([0.0, 0.733, 1.918, 2.857]), rng.uniform(-0.5, 0.5, (4, 2))) for _ in range(n)]
    states, _, _, ok = integrate_held(data.equations(), data.train.states_clean[:n, 0], fine, rows)
    assert ok.all()
    return data, rows, fine, states


def _held_split(rows: list, fine: np.ndarray, states: np.ndarray, every: int = 10) -> Split:
    idx = np.arange(0, fine.size, every)
    t = np.broadcast_to(fine[idx], (len(rows), idx.size)).copy()
    pairs = [forcing_at_samples(t[i], rows[i], "previous", str(i)) for i in range(len(rows))]
    s = states[:, idx]
    return Split(
        t=t,
        states=s,
        states_clean=s,
        derivs=np.zeros_like(s),
        forces=np.stack([f for f, _ in pairs]),
        actuation=np.zeros((len(rows), 2, 3, 3)),
        switch=np.stack([sw for _, sw in pairs]),
    )


def test_held_rk4_steps_follow_the_true_body_through_the_changes() -> None:
    data, rows, fine, states = _held_tracks()
    split = _held_split(rows, fine, states)
    eom = data.equations()
    held_err = lin_err = 0.0
    for i in range(split.n_traj):
        t, r = jnp.asarray(split.t[i]), jnp.asarray(split.forces[i])
        held = rk4_solve_held(eom, jnp.asarray(split.states[i, 0]), t, r, jnp.asarray(split.switch[i]))
        lin = rk4_solve(lambda x, tt: eom(x, tt, forcing(jnp.zeros((2, 3, 3)), tt, t, r)), held[0], t)
        held_err = max(held_err, float(np.max(np.abs(np.asarray(held) - split.states[i])[:, :2])))
        lin_err = max(lin_err, float(np.max(np.abs(np.asarray(lin) - split.states[i])[:, :2])))
    assert held_err < 1e-7  # RK4 at 0.1 s on smooth parts: 1.4e-8 to 2.5e-8 m over 4 s
    assert lin_err > 1e3 * held_err  # the interpolated force: 1.0 to 1.9 mm


def test_a_held_split_rolls_out_as_predict_does_with_a_held_table() -> None:
    _, rows, fine, states = _held_tracks(n=2)
    split = _held_split(rows, fine, states)
    model = _model()
    got = model.rollout(split)
    assert got.ok.all()
    for i in range(split.n_traj):
        times, forces = rows[i]  # a last row at the end: predict wants the forecast covered
        table = held({None: (np.r_[times, 4.0], np.vstack([forces, forces[-1:]]))}, "previous")
        want = predict_tracks(model, duration=4.0, dt=0.1, initial=split.states[i, 0], forcing_table=table)
        np.testing.assert_allclose(got.states[i], want.states[0], atol=1e-7)


def test_a_held_forcing_table_is_imported_with_its_change_times(tmp_path) -> None:
    _, rows, fine, states = _held_tracks(n=3)
    idx = np.arange(0, fine.size, 10)
    table = pd.DataFrame(
        {
            "traj_id": np.repeat(["a", "b", "c"], idx.size),
            "t": np.tile(fine[idx], 3),
            "x": states[:, idx, 0].ravel(),
            "y": states[:, idx, 1].ravel(),
        }
    )
    thrust = pd.DataFrame(
        {
            "traj_id": np.repeat(["a", "b", "c"], 4),
            "t": np.concatenate([r[0] for r in rows]),
            "Fx": np.concatenate([r[1][:, 0] for r in rows]),
            "Fy": np.concatenate([r[1][:, 1] for r in rows]),
        }
    )
    path = tmp_path / "held.h5"
    data = fhnn.import_table(
        table, path, mass=10, area=0.1, forcing=thrust, forcing_hold="previous", outliers=None
    )
    assert data.extra["import"]["forcing"] == {"hold": "previous", "rows": 12}
    assert data.known_forcing and "forces" in data.measured
    again = read_dataset(path)
    for name in ("train", "val", "test"):
        split = again[name]
        np.testing.assert_array_equal(split.switch, data[name].switch)
        inside = (split.switch[:, :-1] > split.times[:, :-1]) & (split.switch[:, :-1] < split.times[:, 1:])
        assert inside.sum() == 3 * split.n_traj  # each track's three changes, each between samples
    windows = Windows.of(again.train)
    assert windows.switch is not None and "switch" in windows.as_jax()
    with pytest.raises(DataFormatError, match="the forcing table ends at 2.857 s, before the last sample"):
        fhnn.import_table(table, mass=10, area=0.1, forcing=thrust, outliers=None)
    covered = pd.concat([thrust, thrust.groupby("traj_id").tail(1).assign(t=4.0)])
    assert fhnn.import_table(table, mass=10, area=0.1, forcing=covered, outliers=None).train.switch is None


def test_a_change_time_outside_its_interval_is_refused(tmp_path) -> None:
    _, rows, fine, states = _held_tracks(n=3)
    split = _held_split(rows, fine, states)
    bad = dataclasses.replace(split, switch=split.switch + 0.5)
    data = small_dataset("steady_vortex")
    path = write_dataset(dataclasses.replace(data, splits={**data.splits, "train": bad}), tmp_path / "b.h5")
    with pytest.raises(DataFormatError, match="/train/switch of trajectory 0 is 0.6 s, outside its sample"):
        read_dataset(path)


def test_fhnn_import_takes_a_held_forcing_table_and_says_so(tmp_path, capsys) -> None:
    _, rows, fine, states = _held_tracks(n=3)
    idx = np.arange(0, fine.size, 10)
    lines = ["track,time,x,y"] + [
        f"{k},{float(fine[j])!r},{float(states[k, j, 0])!r},{float(states[k, j, 1])!r}"
        for k in range(3)
        for j in idx
    ]
    (tmp_path / "tank.csv").write_text("\n".join(lines) + "\n")
    thrust = ["track,time,Fx,Fy"] + [
        f"{k},{float(t)!r},{float(f[0])!r},{float(f[1])!r}"
        for k in range(3)
        for t, f in zip(*rows[k], strict=True)
    ]
    (tmp_path / "thrust.csv").write_text("\n".join(thrust) + "\n")
    out = tmp_path / "tank.h5"
    argv = ["import", str(tmp_path / "tank.csv"), "-o", str(out), "--mass", "10", "--area", "0.1"]
    argv += [
        "--columns",
        "traj_id=track,t=time",
        "--outliers",
        "off",
        "--forcing",
        str(tmp_path / "thrust.csv"),
    ]
    code, said, err = run_cli([*argv, "--forcing-hold", "previous"], capsys)
    assert code == 0, err
    assert "forcing: 12 rows of a separate table, each row held until the next" in " ".join(said.split())
    data = read_dataset(out)
    assert data.train.switch is not None and data.extra["import"]["forcing"]["hold"] == "previous"
    # the first training track's change times are its forcing rows' (the clock starts at 0 s)
    split, track = data.train, int(data.extra["import"]["traj_ids"]["train"][0])
    inside = (split.switch[0, :-1] > split.times[0, :-1]) & (split.switch[0, :-1] < split.times[0, 1:])
    np.testing.assert_allclose(split.switch[0, :-1][inside], rows[track][0][1:])


@pytest.mark.parametrize("width", [2, 3])
def test_the_training_loss_steps_across_each_change(width: int) -> None:
    """The one-step and multi-step terms of a held batch are RK4 split at each change (the
    model's own field, forces held), not one step under the interpolated force."""
    _, rows, fine, states = _held_tracks(n=2)
    windows = Windows.of(_held_split(rows, fine, states), width)
    inside = (windows.switch[:, :-1] > windows.t[:, :-1]) & (windows.switch[:, :-1] < windows.t[:, 1:])
    windows = windows.subset(np.r_[np.flatnonzero(inside.any(axis=1)), 0:4])  # with and without changes
    model = _model()
    batch = {**windows.as_jax(), "weight": jnp.ones(len(windows))}  # every window alike
    scales = (jnp.ones(4), jnp.ones(4))
    got = model.loss_terms(batch, scales)

    def path(s, t, u, switch) -> jnp.ndarray:
        return rk4_solve_held(lambda x, tt, f: model(x, tt, f), s[0], t, u, switch)

    paths = jax.jit(jax.vmap(path))(batch["s"], batch["t"], batch["dforce"], batch["switch"])
    want = float(jnp.mean((paths[:, 1] - batch["s"][:, 1]) ** 2))
    assert float(got["step"]) == pytest.approx(want, rel=1e-12)
    interpolated = model.loss_terms({k: v for k, v in batch.items() if k != "switch"}, scales)
    assert abs(float(interpolated["step"]) - want) > 1e-6 * want
    if width == 3:
        want_shoot = float(jnp.mean((paths[:, 1:, :2] - batch["s"][:, 1:, :2]) ** 2))
        assert float(got["shoot"]) == pytest.approx(want_shoot, rel=1e-12)
