"""Ensembles of turning-body models: bootstraps of the training tracks, members in one folder,
intervals for the masses, the damping and forecasts (:mod:`fhnn.api.planar_ensemble`)."""

from __future__ import annotations

import dataclasses
import json
import shutil

import jax
import numpy as np
import pandas as pd
import pytest
from scipy.stats import t as student_t

from fhnn.api.planar import load_turning
from fhnn.api.planar_ensemble import (
    ensemble_coefficients,
    is_turning_ensemble,
    load_turning_ensemble,
    predict_turning_ensemble,
    train_turning_ensemble,
)
from fhnn.api.planar_forecast import forecast_turning
from fhnn.data.planar import read_planar, simulate_planar, write_planar
from fhnn.data.planar_table import observed_table
from fhnn.errors import ConfigError, DataFormatError
from fhnn.models.planar import planar_arguments
from fhnn.training.ensemble import start_ensemble
from fhnn.training.planar_ensemble import bootstrap_indices, bootstrap_planar

from .conftest import run_cli


@pytest.fixture(scope="module")
def planar_data():
    """The data of ``tests/test_planar.py``'s command-line test (the same shapes: its compiled
    programs serve these tests too)."""
    return simulate_planar("turning_vortex", n_traj=6, duration=1.0, test_duration=2.0, seed=4)


def test_a_bootstrap_resamples_the_training_tracks_and_nothing_else(planar_data) -> None:
    pick = bootstrap_indices(30, 3)
    assert pick.shape == (30,) and np.all(np.diff(pick) >= 0) and pick.min() >= 0 and pick.max() < 30
    np.testing.assert_array_equal(pick, bootstrap_indices(30, 3))  # the seed fixes it
    draws = [tuple(bootstrap_indices(30, s)) for s in range(20)]
    assert len(set(draws)) == 20 and all(len(set(d)) < 30 for d in draws)  # seeds differ; repeats
    # every index as likely: over many draws each is picked about once per draw
    counts = np.bincount(np.concatenate([bootstrap_indices(30, s) for s in range(2000)]), minlength=30)
    assert np.all(np.abs(counts / 2000 - 1.0) < 0.1)
    n = planar_data.splits["train"].t.shape[0]
    pick = bootstrap_indices(n, 3)
    resampled = bootstrap_planar(planar_data, 3)
    train, source = resampled.splits["train"], planar_data.splits["train"]
    for name in ("t", "states", "states_clean", "forces", "thrust", "lengths"):
        np.testing.assert_array_equal(getattr(train, name), getattr(source, name)[pick])
    assert resampled.splits["val"] is planar_data.splits["val"]
    assert resampled.splits["test"] is planar_data.splits["test"]
    assert resampled.params == planar_data.params and resampled.mass == planar_data.mass
    with pytest.raises(ValueError, match="at least 2 training trajectories, got 1"):
        bootstrap_indices(1, 0)


#: ``fhnn turning train DATA -o ENS`` with a few Adam steps.
TRAIN = ["--adam-steps", "10", "--lbfgs-steps", "0"]


@pytest.fixture(scope="module")
def ensemble(planar_data, tmp_path_factory):
    """The data file and the folder holding ``ens``: ``fhnn turning train DATA -o ens --seeds 2
    --seed 4`` (a few Adam steps)."""
    from fhnn.cli.app import main

    folder = tmp_path_factory.mktemp("planar_ensemble")
    data = write_planar(planar_data, folder / "t.h5")
    with pytest.raises(SystemExit) as info:
        main(
            [
                "turning",
                "train",
                str(data),
                "-o",
                str(folder / "ens"),
                *TRAIN,
                "--seeds",
                "2",
                "--seed",
                "4",
                "-q",
            ]
        )
    assert info.value.code == 0
    return folder, data


def test_the_members_train_on_their_bootstraps_and_resume(ensemble, capsys) -> None:
    """Member S trains with seed S on bootstrap S (its stored data-derived arguments are those of
    the bootstrap); the same command again trains nothing; bad requests are refused in one line."""
    folder, data = ensemble
    ens = folder / "ens"
    assert is_turning_ensemble(ens)
    manifest = json.loads((ens / "ensemble.json").read_text())
    assert manifest["seeds"] == [4, 5] and manifest["body"] == "turning" and manifest["bootstrap"]
    dataset = read_planar(data)
    for seed in (4, 5):
        run = json.loads((ens / f"seed-{seed}" / "run.json").read_text())
        assert run["training"]["seed"] == seed
        assert run["arguments"] == pytest.approx(planar_arguments(bootstrap_planar(dataset, seed)), rel=1e-15)
    weights = [(ens / f"seed-{s}" / "model.eqx").read_bytes() for s in (4, 5)]
    assert weights[0] != weights[1]
    # the same command again: both members kept, nothing retrained
    argv = ["turning", "train", str(data), "-o", str(ens), *TRAIN]
    code, out, err = run_cli([*argv, "--seeds", "2", "--seed", "4", "-q"], capsys)
    assert code == 0, err
    assert "an ensemble of 2 members (0 trained now, 2 kept)" in " ".join(out.split())
    assert [(ens / f"seed-{s}" / "model.eqx").read_bytes() for s in (4, 5)] == weights
    # refused in one line
    code, _, err = run_cli([*argv, "--seeds", "0"], capsys)
    assert code == 2 and "--seeds must be at least 1, got 0" in err
    code, _, err = run_cli([*argv, "--seeds", "3", "--seed", "4"], capsys)
    assert code == 2 and "holds an ensemble of seeds 4, 5, not 4, 5, 6" in " ".join(err.split())
    point = folder / "point"
    start_ensemble(point, [0, 1])
    with pytest.raises(ConfigError, match="holds a point body's ensemble"):
        train_turning_ensemble(data, point, members=2)
    with pytest.raises(DataFormatError, match="not an ensemble of turning-body models"):
        load_turning_ensemble(point)
    with pytest.raises(ConfigError, match="at least 2 members, got 1"):
        train_turning_ensemble(data, folder / "one", members=1)
    assert not (folder / "one").exists()


def test_intervals_are_the_members_t_intervals_and_say_whether_they_hold_the_truth(ensemble) -> None:
    """The masses' and the equivalent damping's intervals are mean ∓ t(0.95; N−1)·s·√(1 + 1/N) of
    the members' values, recomputed here by hand; ``inside`` and ``band_holds`` follow from them."""
    folder, data = ensemble
    models = load_turning_ensemble(folder / "ens")
    dataset = read_planar(data)
    rows, columns = ensemble_coefficients(models, dataset, max_points=50)
    rows = {r["name"]: r for r in rows}
    masses = np.stack([np.asarray(m.added_mass()) for m in models])
    half = student_t.ppf(0.95, 1) * masses.std(axis=0, ddof=1) * np.sqrt(1.5)
    for i, name in enumerate(("m_11", "m_22", "m_66")):
        r = rows[name]
        assert r["value"] == pytest.approx(np.median(masses[:, i]), rel=1e-14)
        assert (r["lo"], r["hi"]) == pytest.approx(
            (masses[:, i].mean() - half[i], masses[:, i].mean() + half[i])
        )
        true = dataset.params["added_mass"][i]
        assert r["true"] == true and r["inside"] == (r["lo"] <= true <= r["hi"])
    nu = np.stack([columns["u_r"], columns["v_r"], columns["r_r"]], axis=1)
    assert nu.shape == (50, 3)
    true_force = np.asarray(jax.vmap(dataset.truth().damping())(nu))
    for i, (name, force) in enumerate((("X_d/u_r", "X_d"), ("Y_d/v_r", "Y_d"), ("N_d/r_r", "N_d"))):
        ratios = [
            float(np.asarray(jax.vmap(m.damping)(nu))[:, i] @ nu[:, i] / (nu[:, i] @ nu[:, i]))
            for m in models
        ]
        r = rows[name]
        assert r["value"] == pytest.approx(np.median(ratios), rel=1e-10)
        assert r["true"] == pytest.approx(true_force[:, i] @ nu[:, i] / (nu[:, i] @ nu[:, i]), rel=1e-12)
        lo, hi = columns[f"{force}_lo"], columns[f"{force}_hi"]
        assert np.all(lo <= columns[force]) and np.all(columns[force] <= hi)
        held = (lo <= true_force[:, i]) & (true_force[:, i] <= hi)
        assert r["band_holds"] == pytest.approx(held.mean(), abs=1e-15)
    with pytest.raises(ValueError, match="at least 2 members, got 1"):
        ensemble_coefficients(models[:1], dataset)


def test_inspect_and_predict_an_ensemble_from_the_command_line(ensemble, capsys) -> None:
    """``turning inspect`` writes the intervals' files; ``turning predict`` of an ensemble whose
    two members are the same model is that model's forecast with a band of zero width."""
    folder, data = ensemble
    ens = folder / "ens"
    code, out, err = run_cli(["turning", "inspect", str(ens), str(data), "--max-points", "50"], capsys)
    assert code == 0, err
    said = " ".join(out.split())
    assert (
        "90 % interval" in said
        and "m_22" in said
        and "least-squares ratio of the surge damping to u_r" in said
        and "N_d/r_r" in said
    )
    table = pd.read_csv(ens / "coefficients.csv")
    assert list(table["name"]) == ["m_11", "m_22", "m_66", "X_d/u_r", "Y_d/v_r", "N_d/r_r"]
    assert len(pd.read_csv(ens / "damping.csv")) == 50 and (ens / "damping.png").stat().st_size > 10_000
    assert "noisy" not in err  # noise-free data: no caution; noisy data: said, the numbers unchanged
    noisy = write_planar(dataclasses.replace(read_planar(data), obs_noise=1e-3), folder / "noisy.h5")
    code, out_noisy, err = run_cli(["turning", "inspect", str(ens), str(noisy), "--max-points", "50"], capsys)
    assert code == 0 and out_noisy == out
    assert "the data are noisy (noise level 0.001): the intervals hold the members' spread" in " ".join(
        err.split()
    )
    # a twin ensemble: both members are seed-4's model
    twin = folder / "twin"
    shutil.copytree(ens, twin)
    shutil.rmtree(twin / "seed-5")
    shutil.copytree(twin / "seed-4", twin / "seed-5")
    history = folder / "history.csv"
    pd.DataFrame(observed_table(read_planar(data))).to_csv(history, index=False)
    out_file = folder / "band.csv"
    code, _, err = run_cli(
        ["turning", "predict", str(twin), "--history", str(history), "--duration", "1", "-o", str(out_file)],
        capsys,
    )
    assert code == 0, err
    band = pd.read_csv(out_file)
    single = forecast_turning(twin / "seed-4", history, 1.0)
    for name in ("x", "y", "heading", "u", "v", "r"):
        np.testing.assert_allclose(band[name], single[name], rtol=0, atol=1e-12)
        np.testing.assert_allclose(band[f"{name}_lo"], single[name], rtol=0, atol=1e-12)
        np.testing.assert_allclose(band[f"{name}_hi"], single[name], rtol=0, atol=1e-12)
    # the real ensemble: a band that holds its median; from the smoothed last state, as
    # predict_turning_ensemble forecasts
    band = forecast_turning(ens, history, 1.0, fit_window=0)
    plain = predict_turning_ensemble(ens, history, 1.0)
    np.testing.assert_allclose(band.drop(columns="traj_id"), plain.drop(columns="traj_id"), rtol=1e-12)
    assert (
        np.all(band["x_lo"] <= band["x"])
        and np.all(band["x"] <= band["x_hi"])
        and np.any(band["x_hi"] > band["x_lo"])
    )
    # a member missing: one line saying how to finish
    shutil.rmtree(twin / "seed-5")
    code, _, err = run_cli(["turning", "inspect", str(twin), str(data)], capsys)
    assert code == 2 and "member(s) seed-5 not trained yet" in err
    assert load_turning(ens / "seed-4") is not None
