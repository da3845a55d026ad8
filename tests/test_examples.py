"""The worked example in examples/ runs end to end in its fast mode, and writes what it promises."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.csv as pacsv
import xarray as xr

ROOT = Path(__file__).resolve().parents[1]


def test_own_data_example_runs_from_table_to_forecast_band(tmp_path: Path) -> None:
    out = tmp_path / "ex"
    run = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "own_data.py"), "--fast", "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    # every step a user types is shown, in order
    steps = [line.split()[2] for line in run.stdout.splitlines() if line.startswith("$ fhnn ")]
    assert steps == ["import", "info", "train", "inspect", "predict"]
    table = pacsv.read_csv(out / "track.csv").column_names
    assert table == ["traj_id", "t", "x", "y", "Fx", "Fy"]  # positions and the known thrust only
    assert sorted(p.name for p in (out / "ens").iterdir() if p.is_dir()) == ["seed-0", "seed-1"]
    coef = pacsv.read_csv(out / "ens" / "coefficients.csv").to_pydict()
    assert {"m_ax_lo", "m_ax_hi", "c_l_lo", "c_l_hi"} <= set(coef)
    with xr.open_dataset(out / "ens" / "flow.nc", engine="h5netcdf") as flow:
        assert {"u_lo", "u_hi", "psi"} <= set(flow.data_vars)
    forecast = pacsv.read_csv(out / "forecast.csv").to_pydict()
    x, lo, hi = (np.asarray(forecast[c]) for c in ("x", "x_lo", "x_hi"))
    assert len(x) > 0 and np.all(lo <= x + 1e-12) and np.all(x <= hi + 1e-12)
    png = out / "forecast.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


def test_station_keeping_example_holds_the_body_where_it_would_drift(tmp_path: Path) -> None:
    """examples/station_keeping.py --fast: model-predictive control with the true 3-DOF model
    keeps the body within a hundredth of the distance it drifts without thrust."""
    import json

    run = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "station_keeping.py"), "--fast", "--json"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    result = json.loads(run.stdout.strip().splitlines()[-1])
    assert result["drift"] > 0.1  # the current carries an uncontrolled body away
    assert result["true_model"] < 0.01 * result["drift"]
    refused = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "station_keeping.py")], capture_output=True, text=True
    )
    assert refused.returncode == 2 and "give --run RUN" in refused.stderr
