"""Ensembles (``fhnn train --seeds N``): members trained into one folder, resumed, inspected with
median and 90 % intervals, evaluated member by member and on average, forecast with a band; misuse
refused in one line."""

from __future__ import annotations

import json
import re
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr

from fhnn.cli.app import main
from fhnn.data.dataset import read_dataset, write_dataset
from fhnn.training.ensemble import member_folder
from fhnn.training.run import Run

from .conftest import small_dataset

TRAIN = ["--plan", "adam", "--steps", "6", "--set", "model.width=8", "--set", "train.val_every=3", "-q"]


def run(argv, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    captured = capsys.readouterr()
    return info.value.code, captured.out, captured.err


@pytest.fixture(scope="module")
def ensemble(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("ens")
    # test_first_use's data set: its evaluation's rollouts are the same programs
    data = small_dataset("steady_vortex", n_traj=6, duration=2.0, test_duration=3.0)
    write_dataset(data, folder / "data.h5")
    with pytest.raises(SystemExit) as info:
        main(["train", str(folder / "data.h5"), "-o", str(folder / "ens"), "--seeds", "3", *TRAIN])
    assert info.value.code == 0
    return folder


def test_members_are_runs_with_consecutive_seeds_and_resume(ensemble, capsys):
    ens = ensemble / "ens"
    assert json.loads((ens / "ensemble.json").read_text())["seeds"] == [0, 1, 2]
    members = [Run.load(member_folder(ens, s)) for s in range(3)]
    assert [r.train_config.seed for r in members] == [0, 1, 2]
    assert all(r.train_config.bootstrap for r in members)  # each on its own resample
    assert all(r.finished for r in members)
    weights = [np.asarray(r.state.best_model.flow.mlp.layers[0].weight) for r in members]
    assert not np.array_equal(weights[0], weights[1])  # other seeds, other initialisation
    # the same command again: every member is finished, nothing is trained
    code, out, _ = run(
        ["train", str(ensemble / "data.h5"), "-o", str(ens), "--seeds", "3", *TRAIN[:-1]], capsys
    )
    assert code == 0 and out.count("nothing to do") == 3
    # other seeds into the same folder, a single run into it, or an ensemble into a single run: refused
    for argv, message in (
        (["--seeds", "3", "--seed", "5"], "holds an ensemble of seeds 0, 1, 2, not 5, 6, 7"),
        (["--seeds", "1"], "holds an ensemble; resume it without --seeds"),
        (["--seeds", "0"], "--seeds must be >= 1, got 0"),
    ):
        code, _, err = run(["train", str(ensemble / "data.h5"), "-o", str(ens), *argv, *TRAIN], capsys)
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    code, _, err = run(
        ["train", str(ensemble / "data.h5"), "-o", str(member_folder(ens, 0)), "--seeds", "2", *TRAIN], capsys
    )
    assert code == 2 and "holds a single run, not an ensemble" in err


def test_evaluate_gives_each_member_and_their_mean(ensemble, capsys):
    """An ensemble's errors are its members' own (as ``fhnn evaluate MEMBER`` gives them), and
    the table and ``mean`` are their mean; diverged trajectories are summed."""
    ens = ensemble / "ens"
    code, out, err = run(["evaluate", str(ens), "--horizons", "1,2", "--json"], capsys)
    assert code == 0, err
    result = json.loads(out)
    assert sorted(result["members"]) == ["seed-0", "seed-1", "seed-2"]
    singles = []
    for seed in (0, 1, 2):
        code, out, err = run(
            ["evaluate", str(member_folder(ens, seed)), "--horizons", "1,2", "--json"], capsys
        )
        assert code == 0, err
        singles.append(json.loads(out))
        assert singles[-1] == result["members"][f"seed-{seed}"]
    for h in ("1", "2"):
        values = np.array([s[h]["rmse_pos"] for s in singles])
        assert values.min() < values.max()  # the members differ ...
        # ... and are averaged
        assert result["mean"][h]["rmse_pos"] == pytest.approx(values.mean(), rel=1e-12)
        assert result["std"][h]["rmse_pos"] == pytest.approx(values.std(), rel=1e-12)
        assert result["mean"][h]["diverged"] == sum(s[h]["diverged"] for s in singles)
    assert result["diverged_count"] == sum(s["diverged_count"] for s in singles)
    code, out, err = run(["evaluate", str(ens), "--horizons", "1,2"], capsys)
    assert code == 0, err
    assert "mean over its 3 members" in " ".join(out.split())
    assert f"{result['mean']['2']['rmse_pos']:.3g}" in out


def test_inspect_gives_the_members_median_and_intervals(ensemble, capsys):
    ens = ensemble / "ens"
    code, out, _ = run(["inspect", str(ens), "--json"], capsys)
    assert code == 0
    report = json.loads(out)
    assert report["members"] == 3 and report["forced"]
    # each member's flow summarised (these short runs' flows are far from the vortex: the
    # numbers are tested on exact flows in test_flow_summary.py); the text gives the interval
    assert len(report["flow_summary"]) == 3
    for summary in report["flow_summary"]:
        assert summary["vortex"] == (summary["explained"] >= 0.9) and summary["explained"] <= 1.0
        assert summary["speed_range"][0] <= summary["speed_range"][1]
    code, text, _ = run(["inspect", str(ens)], capsys)
    (line,) = [x for x in text.splitlines() if x.startswith("flow: ")]
    assert re.search(r"(circulation|ω =) \S+ \S+ \[\S+, \S+\]", line), line
    for name in ("m_ax", "m_ay", "c_q", "c_l", "drag", "c_l/(M+m_ax)", "drag/(M+m_ay)"):
        row = report["coefficients"][name]
        assert row["lo"] <= row["median"] <= row["hi"]
        assert 0.0 <= row["coverage"] <= 1.0 and row["true"] > 0
    # the total drag over the inertia, (½ρA c_q σ + c_l) / (M + m_ay): steady_vortex's true m_ay is
    # one constant, so the ratio's median over the points is the drag's median over M + m_ay
    body = read_dataset(ensemble / "data.h5").constants()
    rows = report["coefficients"]
    assert rows["drag/(M+m_ay)"]["true"] == pytest.approx(
        rows["drag"]["true"] / (body["M"] + rows["m_ay"]["true"]), rel=1e-12
    )
    table = read_table_columns(ens / "coefficients.csv")
    assert list(table)[:5] == ["r", "sigma", "m_ax", "m_ax_lo", "m_ax_hi"]
    assert set(table) >= {f"{n}{e}" for n in ("m_ay", "c_q", "c_l") for e in ("", "_lo", "_hi")}
    # the columns are the members' own median and the ends of mean ± t(0.95; 2) s √(1 + 1/3) at
    # each (r, σ) (t(0.95; 2) = 2.9199855804)
    # ... and the total drag coefficient ½ρA c_q σ + c_l [N·s/m] of each member at that σ
    models = [Run.load(member_folder(ens, s)).state.best_model for s in range(3)]
    body = read_dataset(ensemble / "data.h5").constants()
    for row in (0, len(table["r"]) // 2):
        r, sigma = table["r"][row], table["sigma"][row]
        values = np.stack([np.asarray(m.coefficients(jnp.asarray(r), jnp.asarray(sigma))) for m in models])
        drag = 0.5 * body["rho"] * body["A"] * values[:, 2] * sigma + values[:, 3]
        values = np.column_stack([values, drag])
        for i, name in enumerate(("m_ax", "m_ay", "c_q", "c_l", "drag")):
            half = 2.9199855804 * np.std(values[:, i], ddof=1) * np.sqrt(4 / 3)
            lo, hi = np.mean(values[:, i]) - half, np.mean(values[:, i]) + half
            assert table[name][row] == pytest.approx(np.median(values[:, i]), rel=1e-12)
            assert table[f"{name}_lo"][row] == pytest.approx(lo, rel=1e-12)
            assert table[f"{name}_hi"][row] == pytest.approx(hi, rel=1e-12)
    assert np.all(table["m_ax_lo"] <= table["m_ax"]) and np.all(table["m_ax"] <= table["m_ax_hi"])
    assert np.any(table["c_q_lo"] < table["c_q_hi"])  # the members differ
    with xr.open_dataset(ens / "flow.nc", engine="h5netcdf") as flow:
        assert {"u", "u_lo", "u_hi", "v", "v_lo", "v_hi", "psi", "psi_lo", "psi_hi"} <= set(flow.data_vars)
        assert flow.attrs["members"] == 3
        u, lo, hi = (np.asarray(flow[k]) for k in ("u", "u_lo", "u_hi"))
        seen = np.isfinite(u)
        assert seen.any() and np.all(lo[seen] <= u[seen]) and np.all(u[seen] <= hi[seen])
    code, out, _ = run(["inspect", str(ens)], capsys)
    assert code == 0 and "ensemble of 3 runs" in out and "90 % interval" in out
    said = " ".join(out.split())
    assert (
        re.search(r"│ +drag(?: \[N·s/m\])? +│", out)
        and "the data fix their sum, the total drag coefficient drag =" in said
    )
    assert (
        "members trained on bootstrap weightings of the data, so it holds the data's sampling noise and "
        "the initialisation's, not a bias that every member shares" in said
    )


def test_predict_from_an_ensemble_gives_the_median_and_a_band(ensemble, capsys):
    ens = ensemble / "ens"
    out_csv = ensemble / "forecast.csv"
    code, _, _ = run(
        [
            "predict",
            str(ens),
            "--initial",
            "1.0,0.5,0.1,-0.2",
            "--duration",
            "2",
            "--dt",
            "0.5",
            "-o",
            str(out_csv),
        ],
        capsys,
    )
    assert code == 0
    table = read_table_columns(out_csv)
    assert set(table) >= {"x", "x_lo", "x_hi", "vy", "vy_lo", "vy_hi"}
    assert table["x"][0] == pytest.approx(1.0) and table["x_lo"][0] == pytest.approx(1.0)
    for name in ("x", "y", "vx", "vy"):
        assert np.all(table[f"{name}_lo"] <= table[name] + 1e-15)
        assert np.all(table[name] <= table[f"{name}_hi"] + 1e-15)
    assert table["x_hi"][-1] > table["x_lo"][-1]  # the members' forecasts part


def read_table_columns(path: Path) -> dict[str, np.ndarray]:
    import pyarrow.csv as pacsv

    table = pacsv.read_csv(path)
    return {name: np.asarray(table.column(name)) for name in table.column_names}
