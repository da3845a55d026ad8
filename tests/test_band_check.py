"""A forecast band is checked on the validation tracks before it is shown: how often it holds the
observations, and by how much it must widen to hold what it claims."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import fhnn
from fhnn.api.predict import BAND_FILE
from fhnn.data.observation import observe
from fhnn.evaluation.predict import Forecast, band_scale, widened

from .conftest import small_dataset


def _band(half: float) -> Forecast:
    """One track: median x = y = 0 for 10 s, band ±``half`` [m]."""
    t = np.linspace(0.0, 10.0, 101)[None]
    states = np.zeros((1, 101, 4))
    band = np.stack([states - half, states + half])
    return Forecast(["a"], t, states, np.array([True]), np.array([np.nan]), band=band)


def test_band_scale_finds_the_coverage_and_the_widening_that_holds_the_level() -> None:
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0.0, 10.0, 20_000))
    pos = rng.normal(0.0, 1.0, (t.size, 2))  # N(0, 1) about the median
    half = 1.6448536269514722 / 2  # a band half as wide as a true 90 % band
    coverage, scale, points = band_scale(_band(half), [(t, pos)], noise=0.0, level=0.9)
    assert points == t.size
    assert coverage == pytest.approx(0.5953, abs=0.01)  # P(|Z| ≤ 0.822)
    assert scale == pytest.approx(2.0, rel=0.02)
    # noise of std 1 in the observations, a band as wide as the noise alone would make: no widening
    _, scale, _ = band_scale(_band(1e-9), [(t, pos)], noise=1.0, level=0.9)
    assert scale == pytest.approx(1.0, abs=0.05)
    wide = widened(_band(half), 2.0)
    np.testing.assert_allclose(wide.band[1] - wide.states, 2 * half)


def test_a_band_held_by_too_few_observations_is_widened_and_said_so(tmp_path: Path) -> None:
    fine = small_dataset("steady_vortex", n_traj=8, duration=4.0, test_duration=4.0, dt=0.01)
    table = observe(fine, step=0.05, jitter=0.3, noise=1e-3, seed=2)
    data = fhnn.import_table(pd.DataFrame(table), mass=10.0, area=0.02, split="50/40/10")
    quick = {"train.steps": 40, "train.lbfgs_steps": 0, "train.track_steps": 0, "train.val_every": 20}
    fit = fhnn.train(data, tmp_path / "run", settings=quick, progress=False)
    history = pd.DataFrame({k: v[table["t"] <= 1.0] for k, v in table.items()})
    raw = fhnn.predict(fit, 2.0, history=history, samples=8, check=False)
    shown = fhnn.predict(fit, 2.0, history=history, samples=8)
    kept = json.loads((tmp_path / "run" / BAND_FILE).read_text())["check"]
    assert kept["tracks"] >= len(data.extra["import"]["traj_ids"]["val"]) / 2 and kept["points"] > 40
    assert 2.5 < kept["horizon"] <= 3.0  # the 4 s tracks less their 1 s history
    assert 0.0 <= kept["coverage"] < 0.9 and kept["scale"] > 1.0  # 40 steps: far from the truth
    assert any("validation tracks the 90% band held" in n for n in shown.notes)
    for name in ("x", "y"):
        np.testing.assert_allclose(
            shown.columns[f"{name}_hi"] - shown.columns[name],
            kept["scale"] * (raw.columns[f"{name}_hi"] - raw.columns[name]),
            rtol=1e-9,
            atol=1e-12,
        )
    before = (tmp_path / "run" / BAND_FILE).stat().st_mtime_ns
    fhnn.predict(fit, 2.0, history=history, samples=8)  # the same weights: the kept check
    assert (tmp_path / "run" / BAND_FILE).stat().st_mtime_ns == before
