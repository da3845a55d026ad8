"""Users' own data, end to end: a tracker's noisy, irregular positions → ``fhnn import`` → ``fhnn
train`` (its defaults) → recovery against the simulator's truth and held-out prediction errors.

The data are issue 14's: ``steady_vortex`` with actuation, 70 trajectories of 20 s simulated at
0.01 s, observed about every 0.05 s (each interval drawn from 0.05·U(0.7, 1.3) s), positions only
with N(0, (1 mm)²) noise, 5 % of rows dropped, rows shuffled; split 70/20/10 by ``fhnn import``.
Every step is the command a user runs (in this process, through :func:`fhnn.cli.app.main`); only
the scoring reads the simulator's truth:

- import: wall time, the noise level it sees, the velocity estimate's RMS error;
- coefficients (masses, c_l; c_q per σ band with the share of quadratic drag), the total drag
  ``½ρA c_q σ + c_l`` (overall and per σ band) and flow against the truth over the covered region
  (σ in the true flow), as ``fhnn inspect`` scores simulated data;
- RMSE(pos) at 1 s and 5 s of rollouts of the held-out (test) trajectories from their first
  imported state (observed position, estimated velocity), against the clean truth and against the
  noisy observations;
- ``fhnn predict`` from the first second of each held-out track (its start state fitted there,
  forces from the track's record): RMSE(pos) at 1 s and 5 s against the clean truth, and the
  Liu–Weisberg skill at 5 s;
- import speed on 1,000 trajectories × 2,000 rows (a random walk; no training), by default and
  with each smoother (``--speed-only``: that alone, into ``result_import_speed.json``).

Usage::

    python benchmarks/own_data.py [--out DIR] [--set NAME=VALUE ...] [--smoother NAME] [--seeds N]
        [--no-forcing] [--noise STD] [--glitches FRACTION] [--import-arg ARG ...] [--skip-speed]
        [--speed-only] [--reuse-run]

``--set`` is passed to ``fhnn train`` (to compare settings on validation; the defaults are what
the numbers in the README and the issue notes use). ``--noise`` changes the position noise (1 mm
by default): with ``1e-6`` the errors left are the method's own, not the noise's. ``--glitches``
moves a fraction of the positions by 2-50 cm (:func:`add_glitches`), and ``--import-arg`` passes
arguments to ``fhnn import`` (``--import-arg=--outliers --import-arg=off``: keep the glitches).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import time
from pathlib import Path

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from _common import RESULTS, seed_role, stamp

from fhnn.cli.app import main as fhnn
from fhnn.data.dataset import Dataset, read_dataset, write_dataset
from fhnn.data.observation import observe
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.data.table import write_table
from fhnn.errors import DataFormatError
from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery
from fhnn.physics.scenarios import get_scenario
from fhnn.training.run import Run


def run_cli(*args: str) -> None:
    try:
        fhnn(list(args))
    except SystemExit as exc:
        if exc.code not in (0, None):
            raise RuntimeError(f"fhnn {' '.join(args)} exited {exc.code}") from None


#: How the tracker observes the simulation (issue 14): about every 0.05 s (±30 %), 5 % of rows
#: dropped; the position noise and the seed are :func:`make_data`'s.
OBSERVED = {"step": 0.05, "jitter": 0.3, "drop": 0.05}


def data_suffix(
    no_forcing: bool, noise: float, glitches: float = 0.0, import_args: tuple[str, ...] | list[str] = ()
) -> str:
    """What the file names of a variant of the data carry: no forcing, another position noise,
    glitches, and (imported data sets and runs only) the arguments given to ``fhnn import``."""
    return (
        ("_noforce" if no_forcing else "")
        + (f"_noise{noise:g}" if noise != 1e-3 else "")
        + (f"_glitches{glitches:g}" if glitches else "")
        + "".join(a.strip("-") for a in import_args)
    )


#: Seed stream of :func:`add_glitches` beside the data seed.
GLITCH_STREAM = 7


def add_glitches(table: dict, fraction: float, seed: int) -> tuple[dict, np.ndarray]:
    """``table`` with the positions of a ``fraction`` of its rows (with values) moved by 2-50 cm in
    a random direction — a tracker's glitches — and the rows moved."""
    rng = np.random.default_rng([seed, GLITCH_STREAM])
    bad = {c: v.copy() for c, v in table.items()}
    rows = np.flatnonzero(~np.isnan(bad["x"]))
    pick = rng.choice(rows, int(fraction * rows.size), replace=False)
    angle, size = rng.uniform(0, 2 * np.pi, pick.size), rng.uniform(0.02, 0.5, pick.size)
    bad["x"][pick] += size * np.cos(angle)
    bad["y"][pick] += size * np.sin(angle)
    return bad, pick


def make_data(
    out: Path,
    data_seed: int,
    *,
    no_forcing: bool = False,
    noise: float = 1e-3,
    smoother: str | None = None,
    glitches: float = 0.0,
    import_args: tuple[str, ...] = (),
    n_traj: int = 70,
    duration: float = 20.0,
) -> tuple[Dataset, dict, dict, Path, float]:
    """Issue 14's data in ``out``: the fine simulation (simulated once, reused), the tracker's table
    (noisy positions; with a fraction ``glitches`` of them glitched, :func:`add_glitches`), the
    same table without noise and with velocities, and the imported data set (``fhnn import``,
    every call, with ``import_args``, which tag its file). ``n_traj`` tracks of ``duration`` [s]
    (other sizes than issue 14's 70 × 20 s tag the fine simulation's file). Returns ``(fine,
    table, table_clean, data path, import seconds)``."""
    sc = get_scenario("steady_vortex")
    size = "" if (n_traj, duration) == (70, 20.0) else f"_{n_traj}x{duration:g}s"
    fine_path = out / f"fine_seed{data_seed}{'_noforce' if no_forcing else ''}{size}.h5"
    suffix = data_suffix(no_forcing, noise, glitches) + size
    if not fine_path.exists():
        config = SimulationConfig.for_scenario(
            sc,
            n_traj=n_traj,
            duration=duration,
            test_duration=duration,
            dt=0.01,
            actuation="none" if no_forcing else "random",
            seed=data_seed,
        )
        write_dataset(simulate_dataset(sc, config), fine_path)
    fine = read_dataset(fine_path)
    observed = dict(**OBSERVED, noise=noise, seed=data_seed + 1)
    table = observe(fine, **observed, forces=not no_forcing)
    table_clean = observe(fine, **{**observed, "noise": 0.0}, velocities=True)
    if glitches:
        table = add_glitches(table, glitches, data_seed)[0]
    csv = write_table(table, out / f"track_seed{data_seed}{suffix}.csv")
    data = out / f"track_seed{data_seed}{data_suffix(no_forcing, noise, glitches, import_args)}{size}.h5"
    start = time.perf_counter()
    data.unlink(missing_ok=True)
    area = str(fine.body_params["A"])
    extra = ["--smoother", smoother] if smoother else []
    run_cli("import", str(csv), "-o", str(data), "--mass", "10", "--area", area, "-q", *extra, *import_args)
    return fine, table, table_clean, data, time.perf_counter() - start


def run_folder(out: Path, data_seed: int, tag: str) -> Path:
    """The folder of the single run trained on data seed ``data_seed`` with the settings ``tag``
    (``"defaults"``: ``fhnn train``'s own) in ``out``."""
    return out / f"run_seed{data_seed}_{tag}"


def trained_run(out: Path, data_seed: int) -> tuple[Dataset, Dataset, Run]:
    """The imported data of data seed ``data_seed`` in ``out`` (imported again, as ``--reuse-run``
    does), the same with the simulator's truth (:func:`with_truth`) and the defaults' single run
    trained on it; a :class:`~fhnn.errors.DataFormatError` where that run is not there."""
    folder = run_folder(out, data_seed, "defaults")
    if not (folder / "run.json").exists():
        raise DataFormatError(
            f"{folder}: no trained run; run benchmarks/own_data.py --data-seed {data_seed} first"
        )
    fine, _, _, data, _ = make_data(out, data_seed)
    imported = read_dataset(data)
    return imported, with_truth(imported, fine), Run.load(folder)


def with_truth(imported: Dataset, truth: Dataset) -> Dataset:
    """``imported`` with the simulator's scenario and body: the recovery functions then score it."""
    return Dataset(
        **{
            **imported.__dict__,
            "scenario": truth.scenario,
            "scenario_params": truth.scenario_params,
            "body_params": truth.body_params,
            "extra": {},
        }
    )


def clean_rows(table_clean: dict, imported: Dataset, name: str, i: int) -> np.ndarray:
    """The rows of ``table_clean`` (in time order) at the imported samples of trajectory ``i`` of
    split ``name`` (the import may have dropped glitches)."""
    record = imported.extra["import"]
    split = imported[name]
    times = split.times[i, : split.sample_counts[i]] + record["time_offset"]
    rows = np.flatnonzero(
        (table_clean["traj_id"] == int(record["traj_ids"][name][i])) & np.isin(table_clean["t"], times)
    )
    rows = rows[np.argsort(table_clean["t"][rows])]
    assert rows.size == times.size, "the clean table lacks imported samples"
    return rows


def clean_positions(table_clean: dict, imported: Dataset, name: str) -> np.ndarray:
    """The clean states at each imported sample of split ``name``, shape ``(N, T, 4)``."""
    split = imported[name]
    out = np.array(split.states)
    for i in range(split.n_traj):
        rows = clean_rows(table_clean, imported, name, i)
        for j, c in enumerate(("x", "y", "vx", "vy")):
            out[i, : rows.size, j] = table_clean[c][rows]
    return out


def rollout_errors(run: Path, imported: Dataset, clean: np.ndarray, horizons: tuple[float, ...]) -> dict:
    """RMSE(pos) of test rollouts from the first imported state (observed position, estimated
    velocity) against the clean truth and the observations, and from the true first state."""
    model = Run.load(run).state.best_model
    split = imported.test
    true_start = np.array(split.states_clean)
    true_start[:, 0] = clean[:, 0]
    runs = {
        "imported_start": model.rollout(split, max(horizons), from_clean=False),
        "true_start": model.rollout(dataclasses.replace(split, states_clean=true_start), max(horizons)),
    }
    out: dict = {}
    for h in horizons:
        for name, ro in runs.items():
            size = ro.t.shape[1]
            sel = ro.mask & (ro.t - ro.t[:, :1] <= h + 1e-9) & (ro.t - ro.t[:, :1] > 0)
            pred = ro.states[..., :2][sel]
            out.setdefault(f"{h:g}", {})[name] = {
                "rmse_pos_vs_truth": float(np.sqrt(np.mean((pred - clean[:, :size, :2][sel]) ** 2))),
                "rmse_pos_vs_observed": float(
                    np.sqrt(np.mean((pred - split.states[:, :size, :2][sel]) ** 2))
                ),
            }
    return out


def forecast_errors(
    run: Path,
    table: dict,
    fine: Dataset | None,
    ids: list[str],
    folder: Path,
    horizons: tuple[float, ...],
    *,
    read: bool = True,
    dt: float = 0.05,
) -> dict:
    """``fhnn predict`` as a forecaster uses it, on the held-out trajectories ``ids``: the first
    second of each one's noisy, gappy observations as ``--history`` (its start state fitted
    there), the recorded forces as ``--forcing``, a forecast of ``max(horizons)`` s every 0.05 s;
    RMSE(pos) against the clean truth over the forecast's samples up to each horizon, and the
    Liu–Weisberg skill at the largest."""
    import pyarrow.csv as pacsv

    from fhnn.evaluation.metrics import liu_weisberg, path_length

    ours = np.isin(table["traj_id"].astype(str), ids)
    early = ours & (table["t"] <= 1.0 + 1e-9)
    forced = "Fx" in table
    history = {c: table[c][early] for c in ("traj_id", "t", "x", "y", "Fx", "Fy") if c in table}
    write_table(history, folder / "history.csv")
    if forced:
        write_table({c: table[c][ours] for c in ("traj_id", "t", "Fx", "Fy")}, folder / "forcing.csv")
    pred_path = folder / "forecast.csv"
    pred_path.unlink(missing_ok=True)
    start = time.perf_counter()
    run_cli(
        "predict",
        str(run),
        "--history",
        str(folder / "history.csv"),
        *(["--forcing", str(folder / "forcing.csv")] if forced else []),
        "--duration",
        f"{max(horizons):g}",
        "--dt",
        f"{dt:g}",
        "-o",
        str(pred_path),
    )
    seconds = time.perf_counter() - start
    if not read:  # the caller reads forecast.csv itself
        return {"seconds": seconds}
    clean = np.concatenate([fine[name].states_clean for name in ("train", "val", "test")])
    step = fine.train.t[1] - fine.train.t[0]
    errors: dict = {h: [] for h in horizons}
    skills = []
    pred = pacsv.read_csv(pred_path).to_pydict()
    pred_ids = np.asarray(pred["traj_id"]).astype(str)
    for traj in dict.fromkeys(pred_ids):
        mine = pred_ids == traj
        t = np.asarray(pred["t"])[mine]
        pos = np.stack([np.asarray(pred["x"])[mine], np.asarray(pred["y"])[mine]], axis=1)
        truth = clean[int(traj), np.rint(t / step).astype(int), :2]
        rel = t - t[0]
        for h in horizons:
            errors[h].append(pos[(rel > 0) & (rel <= h + 1e-9)] - truth[(rel > 0) & (rel <= h + 1e-9)])
        sep = np.linalg.norm(pos[1:] - truth[1:], axis=1)
        skills.append(liu_weisberg(sep, path_length(truth)[1:]))
    return {
        "seconds": seconds,
        "trajectories": len(skills),
        "rmse_pos_vs_truth": {
            f"{h:g}": float(np.sqrt(np.mean(np.concatenate(errors[h]) ** 2))) for h in horizons
        },
        "liu_weisberg_skill": float(np.mean(skills)),
        # the band from the uncertainty of each fitted start state (one model: no members)
        **({"forecast_band": band_scores(pred, fine)} if "x_lo" in pred else {}),
    }


def band_scores(pred: dict, fine: Dataset) -> dict:
    """How often the band of ``fhnn predict``'s output ``pred`` (columns by name, with ``x_lo``
    … ``y_hi``) holds the clean truth of ``fine``: over every forecast time after the start, at
    1 s and 5 s, and the band's median diagonal there [m]."""
    clean = np.concatenate([fine[name].states_clean for name in ("train", "val", "test")])
    step = fine.train.t[1] - fine.train.t[0]
    ids = np.asarray(pred["traj_id"]).astype(int)
    t = np.asarray(pred["t"])
    truth = clean[ids, np.rint(t / step).astype(int), :2]
    inside = np.ones(len(t), bool)
    for j, c in enumerate(("x", "y")):
        inside &= (np.asarray(pred[f"{c}_lo"]) <= truth[:, j]) & (truth[:, j] <= np.asarray(pred[f"{c}_hi"]))
    width = np.hypot(
        np.asarray(pred["x_hi"]) - np.asarray(pred["x_lo"]),
        np.asarray(pred["y_hi"]) - np.asarray(pred["y_lo"]),
    )
    start_t = {i: t[ids == i].min() for i in np.unique(ids)}
    rel = t - np.asarray([start_t[i] for i in ids])
    at = {h: np.isclose(rel, h) for h in (1.0, 5.0)}
    return {
        "truth_inside_share": float(np.mean(inside[rel > 0])),
        "truth_inside_share_at": {f"{h:g}": float(np.mean(inside[m])) for h, m in at.items()},
        "median_band_diagonal_at": {f"{h:g}": float(np.median(width[m])) for h, m in at.items()},
    }


def band_text(fb: dict) -> str:
    """:func:`band_scores` in a line."""
    return (
        f"holds the truth at {fb['truth_inside_share']:.0%} of forecast positions "
        f"(1 s: {fb['truth_inside_share_at']['1']:.0%}, 5 s: {fb['truth_inside_share_at']['5']:.0%}); "
        f"median band diagonal at 5 s {fb['median_band_diagonal_at']['5']:.2e} m"
    )


def validation_forecast(run: Path, table: dict, ids: list[str], folder: Path) -> dict:
    """What a user can score without the truth: ``fhnn predict`` from the first second of each
    validation track, 5 s ahead (0.01 s steps, linearly interpolated to the observation times),
    RMSE(pos) against the track's own noisy observations up to 1 s and 5 s. It judges the model,
    not the velocity estimates (the start state is fitted to the positions): so it compares
    smoothers, where the multi-step validation loss, whose windows start from the estimates, mostly
    compares the estimates."""
    folder.mkdir(exist_ok=True)
    forecast_errors(run, table, None, ids, folder, (5.0,), read=False, dt=0.01)  # no truth read
    import pyarrow.csv as pacsv

    pred = pacsv.read_csv(folder / "forecast.csv").to_pydict()
    ids_all = table["traj_id"].astype(str)
    seen = ~np.isnan(table["x"])
    pred_ids = np.asarray(pred["traj_id"]).astype(str)
    errors: dict = {1.0: [], 5.0: []}
    for traj in ids:
        mine = pred_ids == traj
        t, x, y = (np.asarray(pred[c])[mine] for c in ("t", "x", "y"))
        obs = seen & (ids_all == traj) & (table["t"] > t[0] + 1e-9) & (table["t"] <= t[-1] + 1e-9)
        rel = table["t"][obs] - t[0]
        dx = np.interp(table["t"][obs], t, x) - table["x"][obs]
        dy = np.interp(table["t"][obs], t, y) - table["y"][obs]
        for h in errors:
            errors[h].append(np.r_[dx[rel <= h + 1e-9], dy[rel <= h + 1e-9]])
    return {
        "trajectories": len(ids),
        "rmse_pos_vs_observed": {
            f"{h:g}": float(np.sqrt(np.mean(np.concatenate(e) ** 2))) for h, e in errors.items()
        },
    }


def origin_table(
    table: dict, ids: list[str], every: float = 2.0, span: float = 6.0
) -> tuple[dict, list[str]]:
    """The tracks ``ids`` of ``table`` cut into pieces of ``span`` s starting every ``every`` s of
    each track (as many as fit, with half a second more of the record for the forcing), each a
    track of its own (``ID@START``) with its times from 0: forecast from each piece's first
    second, many origins per track instead of one."""
    ids_all = table["traj_id"].astype(str)
    parts: dict[str, list] = {c: [] for c in table}
    pieces = []
    for traj in ids:
        mine = np.flatnonzero(ids_all == traj)
        t = table["t"][mine]
        t0, end = t.min(), t.max()
        start = t0
        while start + span + 0.5 <= end + 1e-9:
            rows = mine[(t >= start - 1e-9) & (t <= start + span + 0.5 + 1e-9)]
            name = f"{traj}@{start - t0:g}"
            pieces.append(name)
            for c in table:
                column = np.full(rows.size, name) if c == "traj_id" else table[c][rows]
                parts[c].append(column - start if c == "t" else column)
            start += every
    return {c: np.concatenate(v) for c, v in parts.items()}, pieces


def says_not_identifiable(run: Path, data: Path) -> bool:
    """Whether ``fhnn inspect`` (a fresh process, as a user runs it) says the masses and drag
    coefficients are not determined by the data."""
    cmd = [sys.executable, "-c", "from fhnn.cli.app import main; main()", "inspect", str(run), str(data)]
    shown = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    return "NOT determined by the data" in " ".join(shown.split())


def import_speed(folder: Path) -> dict:
    """Wall seconds of ``fhnn import``, each a new process as a user runs it (start-up included),
    of a random walk's positions at irregular times: 1,000 trajectories × 2,000 rows with the
    default smoother (``auto``: the Kalman smoother above 200,000 rows) and with each smoother
    named; and 100 × 2,000 rows (the largest table ``auto`` gives the spline) with the default. A
    random walk is FITPACK's worst case (a knot every ~3.5 samples). The first import (``warm_up``)
    compiles the Kalman smoother into the compilation cache, as a user's first import does; the
    later ones load it from there."""
    rng = np.random.default_rng(0)
    n, rows = 1000, 2000
    t = np.cumsum(rng.uniform(0.035, 0.065, (n, rows)), axis=1)
    pos = np.cumsum(rng.normal(0, 0.01, (n, rows, 2)), axis=1)

    def table(k: int) -> dict:
        return {
            "traj_id": np.repeat(np.arange(k), rows),
            "t": t[:k].ravel(),
            "x": pos[:k, :, 0].ravel(),
            "y": pos[:k, :, 1].ravel(),
        }

    big, small = write_table(table(n), folder / "big.csv"), write_table(table(100), folder / "small.csv")
    out: dict = {"rows": n * rows, "trajectories": n}

    def timed(label: str, path: Path, *smoother: str) -> None:
        target = folder / "big.h5"
        target.unlink(missing_ok=True)
        start = time.perf_counter()
        cli = [sys.executable, "-c", "from fhnn.cli.app import main; main()"]
        args = ["import", str(path), "-o", str(target), "--mass", "10", "--area", "0.1", "-q", *smoother]
        subprocess.run([*cli, *args], check=True)
        out[f"seconds_{label}"] = time.perf_counter() - start
        out.setdefault("smoother_used", {})[label] = read_dataset(target).extra["import"]["smoother"]

    timed("warm_up", small, "--smoother", "kalman")  # compiles the Kalman smoother
    timed("default", big)
    timed("kalman", big, "--smoother", "kalman")
    timed("spline", big, "--smoother", "spline")
    timed("default_100_trajectories", small)
    return out


def recovery_scores(coef: dict) -> dict:
    """The parts of :func:`fhnn.evaluation.recovery.coefficient_recovery`'s result the benchmark
    keeps: mean relative errors of the coefficients, the ratios and the total drag, and per σ band
    the quadratic share of the drag with the max errors of ``c_q`` and of the total drag."""
    return {
        "coefficients_mean_rel": {k: coef[k]["mean_rel"] for k in ("m_ax", "m_ay", "c_q", "c_l")},
        "ratios_mean_rel": {k: v["mean_rel"] for k, v in coef["_ratios"].items()},
        "c_q_by_sigma": [
            {
                "sigma": [b["sigma_lo"], b["sigma_hi"]],
                "quadratic_share": b["quadratic_share"],
                "c_q": b["c_q"],
                "drag": b["drag"],
            }
            for b in coef["_by_sigma"]
        ],
        "drag_mean_rel": coef["_drag"]["mean_rel"],
    }


class MedianCoefficients(eqx.Module):
    """The members' median of each coefficient at ``(r, σ)``: what ``fhnn inspect`` reports for
    an ensemble, as one coefficient function the recovery scores can take."""

    members: tuple

    def __call__(self, r, sigma):
        return jnp.median(jnp.stack([m(r, sigma) for m in self.members]), axis=0)


def ensemble_scores(
    n: int,
    run: Path,
    data: Path,
    out: Path,
    tag: str,
    sets: list[str],
    scored: Dataset,
    fine: Dataset,
    table: dict,
    record: dict,
    previous: dict | None = None,
) -> dict:
    """``fhnn train --seeds n`` on the same data and settings (every member on its own bootstrap
    weighting of the training trajectories, the command's default), then each coefficient's and
    ratio's 90 % interval against the truth
    (:func:`fhnn.experiments.exports.ensemble_intervals`) and ``fhnn predict``'s band on the held-out
    tracks: the share of forecast positions whose truth lies inside the band at each time.
    ``previous``: the result an earlier invocation wrote; where every member had already
    finished, its training time stands (nothing is trained now)."""
    import pyarrow.csv as pacsv

    from fhnn.experiments.exports import ensemble_intervals
    from fhnn.training.ensemble import is_ensemble, member_folders

    ens = out / f"ens{n}_{run.name}"
    try:  # every member trained already (by an earlier invocation)?
        members = member_folders(ens) if is_ensemble(ens) else []
    except DataFormatError:  # a member not trained yet
        members = []
    done = len(members) == n and all(Run.load(f).finished for f in members)
    start = time.perf_counter()
    run_cli("train", str(data), "-o", str(ens), "--seeds", str(n), "-q", *sets)
    seconds = time.perf_counter() - start
    if done and previous and "ensemble" in previous:
        seconds = previous["ensemble"]["train_seconds"]
    models = [Run.load(f).state.best_model for f in member_folders(ens)]
    rows = ensemble_intervals([m.eom for m in models], scored, scored.equations())
    # the forecast band from the ensemble, on the held-out tracks (history, forcing as for the run)
    folder = out / f"ens{n}_forecast"
    folder.mkdir(exist_ok=True)
    forecast_errors(ens, table, fine, list(record["traj_ids"]["test"]), folder, (1.0, 5.0), read=False)
    band = pacsv.read_csv(folder / "forecast.csv").to_pydict()
    median = MedianCoefficients(tuple(m.coefficients for m in models))
    return {
        "members": n,
        "train_seconds": seconds,
        "intervals": rows,
        # the members' median scored as the single run is (the same points and σ bands)
        "median_recovery": recovery_scores(coefficient_recovery(median, scored)),
        "members_mean_rel": [
            recovery_scores(coefficient_recovery(m.coefficients, scored))["coefficients_mean_rel"]
            for m in models
        ],
        "forecast_band": band_scores(band, fine),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("benchmarks/_own_data"))
    p.add_argument("--set", action="append", default=[], help="NAME=VALUE for fhnn train")
    p.add_argument("--data-seed", type=int, default=0)
    p.add_argument("--skip-speed", action="store_true")
    p.add_argument("--result", default=None, help="also write benchmarks/results/RESULT.json")
    p.add_argument(
        "--speed-only",
        action="store_true",
        help="only the import speed (written to benchmarks/results/import_speed.json)",
    )
    p.add_argument(
        "--reuse-run",
        action="store_true",
        help="score a finished run of the same settings instead of training",
    )
    p.add_argument("--smoother", default=None, help="fhnn import --smoother (default: the import's own)")
    p.add_argument(
        "--seeds",
        type=int,
        default=1,
        help="also train an ensemble of this many seeds (fhnn train --seeds: bootstrap members) "
        "and score its 90 %% intervals and forecast band",
    )
    p.add_argument(
        "--noise",
        type=float,
        default=1e-3,
        help="std of the position noise [m] (default 1e-3, issue 14's; other values tag the files)",
    )
    p.add_argument(
        "--no-forcing",
        action="store_true",
        help="the same data simulated without actuation and exported without Fx, Fy (identifiability)",
    )
    p.add_argument(
        "--glitches",
        type=float,
        default=0.0,
        help="move this fraction of the table's positions by 2-50 cm (a tracker's glitches; tags the files)",
    )
    p.add_argument(
        "--import-arg",
        action="append",
        default=[],
        help="an argument for fhnn import, e.g. --import-arg=--outliers --import-arg=off (tags the files)",
    )
    args = p.parse_args()
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    if args.speed_only:
        speed = import_speed(out)
        (out / "result_import_speed.json").write_text(json.dumps(speed, indent=2))
        (RESULTS / "import_speed.json").write_text(json.dumps({**stamp(), **speed}, indent=2))
        print(speed_text(speed))
        return
    fine, table, table_clean, data, import_seconds = make_data(
        out,
        args.data_seed,
        no_forcing=args.no_forcing,
        noise=args.noise,
        smoother=args.smoother,
        glitches=args.glitches,
        import_args=tuple(args.import_arg),
    )
    suffix = data_suffix(args.no_forcing, args.noise, args.glitches, args.import_arg)
    imported = read_dataset(data)
    record = imported.extra["import"]
    # velocity estimate against the truth, over every imported sample
    vel_err = []
    for name in ("train", "val", "test"):
        split = imported[name]
        for i in range(split.n_traj):
            rows = clean_rows(table_clean, imported, name, i)
            true_v = np.stack([table_clean["vx"][rows], table_clean["vy"][rows]], axis=1)
            vel_err.append((split.states[i, : rows.size, 2:] - true_v).ravel())
    vel_rms = float(np.sqrt(np.mean(np.concatenate(vel_err) ** 2)))
    tag = "_".join(s.replace("=", "").replace(".", "") for s in args.set) or "defaults"
    tag += (f"_{args.smoother}" if args.smoother else "") + suffix
    run = run_folder(out, args.data_seed, tag)
    sets = [x for s in args.set for x in ("--set", s)]
    start = time.perf_counter()
    previous = out / f"result_seed{args.data_seed}_{tag}.json"
    if args.reuse_run and (run / "run.json").exists() and Run.load(run).finished:
        # trained by an earlier invocation (same data, same settings): its training time stands
        train_seconds = json.loads(previous.read_text())["train_seconds"] if previous.exists() else None
    else:
        run_cli("train", str(data), "-o", str(run), "-q", *sets)
        train_seconds = time.perf_counter() - start
    model = Run.load(run).state.best_model
    scored = with_truth(imported, fine)
    coef = coefficient_recovery(model.coefficients, scored)
    flow = flow_recovery(model.flow, scored)
    errors = rollout_errors(run, imported, clean_positions(table_clean, imported, "test"), (1.0, 5.0))
    forecasts = forecast_errors(run, table, fine, list(record["traj_ids"]["test"]), out, (1.0, 5.0))
    val_ids = list(record["traj_ids"]["val"])
    val_forecasts = validation_forecast(run, table, val_ids, out / "val_forecast")
    # the same from an origin every 2 s of each validation track: 14 forecasts from the tracks'
    # first seconds vary by ±25 % between models that forecast alike on average
    val_forecasts["origins"] = validation_forecast(run, *origin_table(table, val_ids), out / "val_forecast")
    result = {
        "settings": args.set,
        "smoother": record["smoother"],  # the estimator the import used
        "data_seed": args.data_seed,
        "import_seconds": import_seconds,
        "position_noise_seen": record["position_noise"],
        "velocity_rms_error": vel_rms,
        "velocity_error_estimated": record.get("velocity_error"),  # the import's bootstrap
        "dropped_rows": record["dropped_rows"],
        "train_seconds": train_seconds,
        **recovery_scores(coef),
        "inspect_says_not_identifiable": says_not_identifiable(run, data),
        "flow_rel_l2": flow["rel_l2"],
        "test_rollouts": errors,
        "test_forecasts": forecasts,
        "val_forecasts": val_forecasts,
    }
    if args.seeds > 1:
        earlier = json.loads(previous.read_text()) if args.reuse_run and previous.exists() else None
        result["ensemble"] = ensemble_scores(
            args.seeds, run, data, out, tag, sets, scored, fine, table, record, earlier
        )
    if not args.skip_speed:
        result["import_speed"] = import_speed(out)
    result = {**stamp(), "seed_role": seed_role("own_data", args.data_seed), **result}
    text = json.dumps(result, indent=2)
    previous.write_text(text)
    if args.result:
        (RESULTS / f"{args.result}.json").write_text(text)
    print(text)
    print(
        f"import {import_seconds:.1f} s, noise seen {record['position_noise'] * 1e3:.3f} mm "
        f"(true {args.noise * 1e3:g} mm), "
        f"velocity RMS error {vel_rms * 1e3:.2f} mm/s (the import's estimate "
        f"{(record.get('velocity_error') or float('nan')) * 1e3:.2f}); train "
        + (f"{train_seconds:.0f} s" if train_seconds is not None else "reused")
    )
    print(
        "coefficients mean rel. error: "
        + ", ".join(f"{k} {v:.2%}" for k, v in result["coefficients_mean_rel"].items())
        + f" (target 3 %); flow {flow['rel_l2']:.2%} (target 2 %)"
    )
    print(
        "ratios mean rel. error: "
        + ", ".join(f"{k} {v:.2%}" for k, v in result["ratios_mean_rel"].items())
        + f"; inspect says masses not identifiable: {result['inspect_says_not_identifiable']}"
    )
    print(
        f"total drag ½ρA c_q σ + c_l mean rel. error {result['drag_mean_rel']:.2%}; per σ band "
        "(σ range: quadratic share of the drag, max error of c_q, of the total drag): "
        + ", ".join(
            f"{b['sigma'][0]:.3f}–{b['sigma'][1]:.3f} m/s: {b['quadratic_share']:.0%}, {b['c_q']:.1%}, "
            f"{b['drag']:.1%}"
            for b in result["c_q_by_sigma"]
        )
    )
    print(
        f"test RMSE(pos) at 5 s vs truth {errors['5']['imported_start']['rmse_pos_vs_truth']:.2e} m "
        f"(target 5e-3; from the true first state {errors['5']['true_start']['rmse_pos_vs_truth']:.2e}), "
        f"vs observations {errors['5']['imported_start']['rmse_pos_vs_observed']:.2e} m"
    )
    print(
        f"fhnn predict from 1 s of each held-out track: RMSE(pos) at 1 s "
        f"{forecasts['rmse_pos_vs_truth']['1']:.2e} m, at 5 s {forecasts['rmse_pos_vs_truth']['5']:.2e} m "
        f"(target 5e-3), Liu-Weisberg skill {forecasts['liu_weisberg_skill']:.3f} "
        f"({forecasts['trajectories']} trajectories)"
    )
    if "forecast_band" in forecasts:
        print("  its band (the fitted start states' uncertainty): " + band_text(forecasts["forecast_band"]))
    origins = val_forecasts["origins"]
    print(
        "fhnn predict from 1 s of each validation track, against its observations (no truth): RMSE(pos) "
        + ", ".join(f"at {h} s {v:.2e} m" for h, v in val_forecasts["rmse_pos_vs_observed"].items())
        + "; from an origin every 2 s ("
        + f"{origins['trajectories']} forecasts) "
        + ", ".join(f"at {h} s {v:.2e} m" for h, v in origins["rmse_pos_vs_observed"].items())
    )
    if "ensemble" in result:
        e = result["ensemble"]
        print(f"ensemble of {e['members']} (trained in {e['train_seconds']:.0f} s):")
        for name, r in e["intervals"].items():
            print(
                f"  {name:14s} median {r['median']:.4g}  90 % interval {r['lo']:.4g} – {r['hi']:.4g} "
                f"(width {r['rel_width']:.1%}, target ≤ 10 %)  true {r['true']:.4g}  truth inside at "
                f"{r['coverage']:.0%} of points (target ≥ 90 %)  median error {r['mean_rel']:.2%}"
            )
        m = e["median_recovery"]
        print(
            "  the members' median against the truth: "
            + ", ".join(f"{k} {v:.2%}" for k, v in m["coefficients_mean_rel"].items())
            + ", ratios "
            + ", ".join(f"{v:.2%}" for v in m["ratios_mean_rel"].values())
            + f", total drag {m['drag_mean_rel']:.2%}; max error of c_q per σ band (quadratic share): "
            + ", ".join(f"{b['c_q']:.1%} ({b['quadratic_share']:.0%})" for b in m["c_q_by_sigma"])
        )
        print("  forecast band (members and start states): " + band_text(e["forecast_band"]))
    if "import_speed" in result:
        print(speed_text(result["import_speed"]))


def speed_text(s: dict) -> str:
    """One line of :func:`import_speed`'s result."""
    return (
        f"import of {s['trajectories']} × {s['rows'] // s['trajectories']} rows: default "
        f"({s['smoother_used']['default']}) {s['seconds_default']:.1f} s (target 10 s), kalman "
        f"{s['seconds_kalman']:.1f} s, spline {s['seconds_spline']:.1f} s; 100 × "
        f"{s['rows'] // s['trajectories']} rows, default "
        f"({s['smoother_used']['default_100_trajectories']}) {s['seconds_default_100_trajectories']:.1f} s"
    )


if __name__ == "__main__":
    main()
