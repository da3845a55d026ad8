"""Worked example: a tracker's noisy, irregular positions, from a table to a forecast with a band.

    python examples/own_data.py [--out DIR] [--fast]

Every step is the command a user types (printed before it runs):

1. Make a table as an instrument records it. Here the truth is simulated (``steady_vortex``, a
   Lamb–Oseen vortex, with a known random thrust) and only what a tracker sees is kept: positions
   about every 0.05 s (±30 % jitter) with 1 mm noise, 5 % of rows lost, and the known thrust
   ``Fx, Fy`` — no velocities, no accelerations. Columns ``traj_id, t, x, y, Fx, Fy``.
2. ``fhnn import`` the table (velocities are estimated, and said so), ``fhnn info``.
3. ``fhnn train --seeds 3``: an ensemble of three runs with the default settings.
4. ``fhnn inspect``: added masses, drag and flow with medians and 90 % intervals;
   ``coefficients.csv`` and ``flow.nc`` for other tools.
5. ``fhnn predict``: from the first second of each held-out track (its state fitted there) with
   the known thrust, 5 s ahead, with a band over the ensemble's members and each fitted start
   state's uncertainty.
6. A picture of the forecasts against the truth (``forecast.png``), beside the learned flow and
   coefficients that ``inspect`` drew.

``--fast`` shrinks the data and training to seconds (no whole-track fit) and the ensemble to
two runs (the tests run it so: every command must work); the README's pictures come from a full
run (5 min 35 s on 2 cores with its compiled programs on disk, 12 min 8 s from nothing).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pyarrow.csv as pacsv

from fhnn.cli.app import main as fhnn_main
from fhnn.data.dataset import read_dataset
from fhnn.data.observation import observe
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.data.table import write_table
from fhnn.physics.scenarios import get_scenario


def fhnn(*args: str) -> None:
    """Run one ``fhnn`` command as typed in a shell; stop the example if it fails."""
    print("$ fhnn " + " ".join(shlex.quote(a) for a in args), flush=True)
    try:
        fhnn_main(list(args))
    except SystemExit as exc:
        if exc.code not in (0, None):
            sys.exit(f"fhnn {args[0]} failed (exit {exc.code})")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("examples/_own_data"), help="working folder")
    p.add_argument("--fast", action="store_true", help="tiny data and training (seconds)")
    args = p.parse_args()
    out = args.out
    out.mkdir(parents=True, exist_ok=True)

    # 1. the instrument's table (the truth is kept aside to judge the forecasts)
    scenario = get_scenario("steady_vortex")
    n_traj, duration = (8, 4.0) if args.fast else (70, 20.0)
    truth = simulate_dataset(
        scenario,
        SimulationConfig.for_scenario(
            scenario, n_traj=n_traj, duration=duration, test_duration=duration, dt=0.01, seed=0
        ),
    )
    table = observe(truth, step=0.05, jitter=0.3, noise=1e-3, drop=0.05, seed=1)  # positions only
    write_table(table, out / "track.csv")
    print(f"wrote {out / 'track.csv'}: {len(table['t'])} rows, {int(np.isnan(table['x']).sum())} gaps")

    # 2. import and look
    fhnn(
        "import", str(out / "track.csv"), "-o", str(out / "track.h5"), "--mass", "10", "--area", "0.02", "-q"
    )
    fhnn("info", str(out / "track.h5"))

    # 3. an ensemble of three runs (two with --fast), default settings (resumed if it exists)
    fast = ["--steps", "20", "--set", "model.width=8", "--set", "train.val_every=10"] if args.fast else []
    fast += ["--set", "train.track_steps=0"] if args.fast else []
    members = "2" if args.fast else "3"  # two: the fewest an ensemble's intervals need
    fhnn("train", str(out / "track.h5"), "-o", str(out / "ens"), "--seeds", members, "-q", *fast)

    # 4. what was learned, with intervals; coefficients.csv and flow.nc for other tools
    fhnn("inspect", str(out / "ens"))
    if not args.fast:  # one member's figures for the README: flow.png, coefficients.png
        fhnn("inspect", str(out / "ens" / "seed-0"))

    # 5. forecasts of the held-out tracks from their first second, with the known thrust
    test_ids = read_dataset(out / "track.h5").extra["import"]["traj_ids"]["test"]
    ours = np.isin(table["traj_id"].astype(str), test_ids)
    first = ours & (table["t"] <= 1.0 + 1e-9)
    write_table({c: table[c][first] for c in ("traj_id", "t", "x", "y", "Fx", "Fy")}, out / "history.csv")
    write_table({c: table[c][ours] for c in ("traj_id", "t", "Fx", "Fy")}, out / "thrust.csv")
    horizon = "2" if args.fast else "5"
    fhnn(
        "predict", str(out / "ens"),
        "--history", str(out / "history.csv"), "--forcing", str(out / "thrust.csv"),
        "--duration", horizon, "--dt", "0.05", "-o", str(out / "forecast.csv"),
    )  # fmt: skip

    # 6. the forecasts against the truth
    figure = plot_forecasts(out / "forecast.csv", out / "history.csv", truth, out / "forecast.png")
    print(f"wrote {figure}")


def plot_forecasts(forecast: Path, history: Path, truth, path: Path, tracks: int = 3) -> Path:
    """The first ``tracks`` forecasts (median and 90 % band) against the true paths."""
    pred = pacsv.read_csv(forecast).to_pydict()
    seen = pacsv.read_csv(history).to_pydict()
    clean = np.concatenate([truth[name].states_clean for name in ("train", "val", "test")])
    step = truth.train.t[1] - truth.train.t[0]
    ids = np.asarray(pred["traj_id"]).astype(str)
    shown = list(dict.fromkeys(ids))[:tracks]
    fig, axes = plt.subplots(1, len(shown), figsize=(4 * len(shown), 4), layout="constrained", squeeze=False)
    for ax, tid in zip(axes[0], shown, strict=True):
        rows = ids == tid
        t = np.asarray(pred["t"])[rows]
        k = np.rint(np.arange(0, t[-1] + step / 2, step) / step).astype(int)
        ax.plot(clean[int(tid), k, 0], clean[int(tid), k, 1], color="0.2", lw=1.5, label="truth")
        h = np.asarray(seen["traj_id"]).astype(str) == tid
        ax.plot(
            np.asarray(seen["x"])[h],
            np.asarray(seen["y"])[h],
            ".",
            ms=3,
            color="tab:gray",
            label="observed (1 s)",
        )
        x, y = (np.asarray(pred[c])[rows] for c in ("x", "y"))
        ax.plot(x, y, color="tab:red", lw=1.2, label="forecast (ensemble median)")
        xlo, xhi, ylo, yhi = (np.asarray(pred[c])[rows] for c in ("x_lo", "x_hi", "y_lo", "y_hi"))
        for i in range(0, len(t), max(1, len(t) // 25)):
            ax.add_patch(
                plt.Rectangle(
                    (xlo[i], ylo[i]), xhi[i] - xlo[i], yhi[i] - ylo[i], color="tab:red", alpha=0.15, lw=0
                )
            )
        ax.set_title(f"track {tid}")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_aspect("equal", adjustable="datalim")
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle("fhnn predict from 1 s of noisy positions: forecast, its 90 % band, and the truth")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


if __name__ == "__main__":
    main()
