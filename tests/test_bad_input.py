"""The bad-input matrix: every command, given a bad parameter, option, file or folder, ends with one
line naming the problem (``error: …``), exit status 2, and the files it was pointed at — data sets,
runs, reproduction folders — exactly as they were (same names, bytes and modes, nothing added)."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from fhnn.cli.app import main
from fhnn.data.dataset import write_dataset

from .conftest import small_dataset


@pytest.fixture(scope="module")
def ws(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A workspace holding a good data set, trained runs and one bad file or run per case."""
    ws = tmp_path_factory.mktemp("ws")
    data = write_dataset(
        small_dataset("steady_vortex", n_traj=6, duration=2.0, test_duration=3.0), ws / "d.h5"
    )
    for name, model in (("run", "fhnn"), ("sindy", "sindy")):
        with pytest.raises(SystemExit) as info:
            main(
                [
                    "train",
                    str(data),
                    "-o",
                    str(ws / name),
                    "--model",
                    model,
                    "--plan",
                    "adam",
                    "--steps",
                    "4",
                    "-q",
                    # the FHNN of test_first_use's and test_faults' runs: one compiled program
                    *(["--set", "model.width=8"] if model == "fhnn" else []),
                ]
            )
        assert info.value.code == 0
    raw = data.read_bytes()
    (ws / "cut.h5").write_bytes(raw[: len(raw) // 3])
    (ws / "text.h5").write_text("time,x,y\n0,1,2\n")
    with h5py.File(ws / "foreign.h5", "w") as f:
        f["x"] = 1

    def edited(name: str, edit) -> None:
        shutil.copy(data, ws / name)
        with h5py.File(ws / name, "r+") as f:
            edit(f)

    edited("nodataset.h5", lambda f: f["train"].__delitem__("states"))
    edited(
        "misshaped.h5",
        lambda f: (f["val"].__delitem__("forces"), f["val"].create_dataset("forces", data=np.zeros((2, 3)))),
    )
    edited("nan.h5", lambda f: f["train"]["states"].__setitem__((0, 3, 1), np.nan))
    edited("inf.h5", lambda f: f["test"]["forces"].__setitem__((0, 2, 0), np.inf))
    edited("newer.h5", lambda f: f.attrs.__setitem__("format_version", 9))
    for name, change in (
        ("newer_run", lambda d: (d / "run.json", lambda i: {**i, "format_version": 7})),
        ("corrupt_run", None),
    ):
        shutil.copytree(ws / "run", ws / name)
        if change is not None:
            path, edit = change(ws / name)
            path.write_text(json.dumps(edit(json.loads(path.read_text()))))
    (ws / "corrupt_run" / "best.eqx").write_bytes(b"\0garbage")
    rows = [[str(i), f"{k / 10:g}", str(k), str(i)] for i in range(3) for k in range(4)]

    def csv(header: str, body: list[list[str]]) -> str:
        return header + "\n" + "".join(",".join(r) + "\n" for r in body)

    def edit(row: int, col: int, value: str) -> list[list[str]]:  # row counts data rows from 1
        return [
            [value if (r, c) == (row - 1, col) else v for c, v in enumerate(line)]
            for r, line in enumerate(rows)
        ]

    tables = {
        "good.csv": csv("traj_id,t,x,y", rows),
        "nocol.csv": csv("traj_id,time,x,y", rows),
        "extra.csv": csv("traj_id,t,x,y,z", [[*r, "0"] for r in rows]),
        "halfvel.csv": csv("traj_id,t,x,y,vx", [[*r, "0"] for r in rows]),
        "text.csv": csv("traj_id,t,x,y", edit(7, 2, "two")),
        "when.csv": csv("traj_id,t,x,y", edit(5, 1, "yesterday")),
        "twice.csv": csv("traj_id, t ,x,y,t", [[*r, r[1]] for r in rows]),
        "zones.csv": csv(
            "traj_id,t,x,y", [["1", f"2026-03-01T10:00:0{k}{'Z' * (k != 1)}", "0", "0"] for k in range(3)]
        ),
        "baddate.csv": csv("traj_id,t,x,y", [["1", d, "0", "0"] for d in ("2026-03-01 10:00", "soon")]),
        "inf.csv": csv("traj_id,t,x,y", edit(12, 2, "inf")),
        "dup.csv": csv("traj_id,t,x,y", edit(7, 1, "0.1")),
        "short.csv": csv("traj_id,t,x,y", [*rows, ["9", "0", "0", "0"], ["9", "1", "1", "1"]]),
        "two.csv": csv("traj_id,t,x,y", rows[:8]),
        "empty.csv": "traj_id,t,x,y\n",
        "gaps.csv": csv("traj_id,t,x,y", [[r[0], r[1], "", ""] for r in rows]),
        "table.txt": csv("traj_id,t,x,y", rows),
        "binary.parquet": "not parquet",
        "force.csv": "t,Fx,Fy\n0,0,0\n1,0.5,0\n",
        "force_nofy.csv": "t,Fx\n0,0\n1,0.5\n",
        "force_dup.csv": "t,Fx,Fy\n0,0,0\n1,0.5,0\n1,0,0\n",
        "force_late.csv": "t,Fx,Fy\n0.05,0,0\n1,0.5,0\n",
        "force_short.csv": "t,Fx,Fy\n0,0,0\n0.2,0.5,0\n",
        "force_twice.csv": "t,Fx,Fy\n0,0,0\n0.12,1,0\n0.15,2,0\n1,2,0\n",
        "forced.csv": csv("traj_id,t,x,y,Fx,Fy", [[*r, "0", "0"] for r in rows]),
    }
    for name, text in tables.items():
        (ws / name).write_text(text)
    (ws / "afile").write_text("mine")
    (ws / "locked").mkdir()
    (ws / "bad.toml").write_text("[train]\nlr = \n")
    (ws / "unknown.toml").write_text("[train]\nlearning_rate = 1e-3\n")
    return ws


def _snapshot(folder: Path) -> dict[str, tuple[str, int]]:
    """Every file and folder under ``folder``: its SHA-256 (folders: "") and mode."""
    out = {}
    for path in sorted(folder.rglob("*")):
        digest = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else ""
        out[str(path.relative_to(folder))] = (digest, path.stat().st_mode)
    return out


S = ["simulate", "steady_vortex"]
B = ["--mass", "10", "--area", "0.1"]
I = ["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B]
T = ["train", "{ws}/d.h5"]
P = ["predict", "{ws}/run", "--duration", "1", "--initial", "0,1,0,0"]
#: (arguments — ``{ws}`` is the workspace —, text the one-line message must contain)
CASES = [
    # simulate: parameters, options, output paths
    ([*S, "-o", "{ws}/n.h5", "-p", "gamma=nan"], "gamma must be finite, got 'nan'"),
    ([*S, "-o", "{ws}/n.h5", "-p", "gamma=inf"], "gamma must be finite, got 'inf'"),
    ([*S, "-o", "{ws}/n.h5", "-p", "gamma=abc"], "gamma"),
    ([*S, "-o", "{ws}/n.h5", "-p", "mass=-2"], "mass must be > 0, got -2.0"),
    ([*S, "-o", "{ws}/n.h5", "-p", "gama=2"], "unknown parameter 'gama' for scenario 'steady_vortex'"),
    ([*S, "-o", "{ws}/n.h5", "--dt", "0"], "simulation: dt must be > 0, got 0.0"),
    ([*S, "-o", "{ws}/n.h5", "--dt", "-1e-3"], "simulation: dt must be > 0, got -0.001"),
    ([*S, "-o", "{ws}/n.h5", "--dt", "nan"], "dt must be"),
    ([*S, "-o", "{ws}/n.h5", "--n-traj", "0"], "simulation: n_traj must be >= 1, got 0"),
    ([*S, "-o", "{ws}/n.h5", "--duration", "inf"], "duration must be finite"),
    ([*S, "-o", "{ws}/n.h5", "--duration", "-3"], "duration must be > 0"),
    ([*S, "-o", "{ws}/n.h5", "--seed", "-1"], "seed must be >= 0, got -1"),
    ([*S, "-o", "{ws}/n.h5", "--obs-noise", "-0.1"], "obs_noise must be >= 0"),
    (["simulate", "vortex", "-o", "{ws}/n.h5"], "unknown scenario 'vortex'"),
    ([*S, "-o", "{ws}/n.h5", "--duration", "1e7"], "more than the solver's 200,000 steps"),
    ([*S, "-o", "{ws}/n.h5", "--n-traj", "1000000000"], "need about 1.25e+05 GiB of memory, more than"),
    ([*S, "-o", "{ws}/missing/n.h5"], "output folder '{ws}/missing' does not exist"),
    ([*S, "-o", "{ws}/run"], "output path '{ws}/run' is a folder"),
    ([*S, "-o", "{ws}/afile/n.h5"], "output folder '{ws}/afile' is a file, not a folder"),
    ([*S, "-o", "{ws}/locked/n.h5"], "output folder '{ws}/locked' is not writable"),
    # info: files
    (["info", "{ws}/absent.h5"], "{ws}/absent.h5: no such file"),
    (["info", "{ws}/cut.h5"], "not a readable HDF5 file"),
    (["info", "{ws}/text.h5"], "not a readable HDF5 file"),
    (["info", "{ws}/foreign.h5"], "not an fhnn data set"),
    (["info", "{ws}/nodataset.h5"], "missing dataset /train/states"),
    (["info", "{ws}/misshaped.h5"], "/val/forces has shape (2, 3), expected"),
    (["info", "{ws}/nan.h5"], "/train/states has 1 NaN or infinite value(s)"),
    (["info", "{ws}/inf.h5"], "/test/forces has 1 NaN or infinite value(s)"),
    (["info", "{ws}/newer.h5"], "unsupported format_version 9"),
    (["info", "{ws}/run"], "is a folder, not a data file"),
    # train: data, settings, output, existing runs
    (["train", "{ws}/nan.h5", "-o", "{ws}/r"], "/train/states has 1 NaN or infinite value(s)"),
    (["train", "{ws}/cut.h5", "-o", "{ws}/r"], "not a readable HDF5 file"),
    ([*T, "-o", "{ws}/r", "--steps", "-5"], "steps must be >= 0, got -5"),
    ([*T, "-o", "{ws}/r", "--set", "train.lr=-1"], "lr must be > 0, got -1.0"),
    ([*T, "-o", "{ws}/r", "--set", "train.lr=nan"], "lr must be"),
    ([*T, "-o", "{ws}/r", "--set", "model.width=0"], "width must be > 0, got 0"),
    ([*T, "-o", "{ws}/r", "--set", "train.shoot=100000"], "train.shoot=100000: give longer trajectories"),
    (
        [*T, "-o", "{ws}/r", "--set", "width=8"],
        "unknown setting 'width' for run (did you mean 'model.width'?)",
    ),
    ([*T, "-o", "{ws}/r", "--model", "gru"], "gru"),
    ([*T, "-o", "{ws}/r", "--config", "{ws}/bad.toml"], "bad.toml"),
    ([*T, "-o", "{ws}/r", "--config", "{ws}/unknown.toml"], "unknown setting 'train.learning_rate'"),
    ([*T, "-o", "{ws}/missing/r"], "output folder '{ws}/missing' does not exist"),
    ([*T, "-o", "{ws}/afile"], "output '{ws}/afile' exists and is not a folder"),
    ([*T, "-o", "{ws}/locked/r"], "output folder '{ws}/locked' is not writable"),
    ([*T, "-o", "{ws}/run", "--model", "node"], "checkpoint is a 'fhnn' model, not 'node'"),
    ([*T, "-o", "{ws}/run", "--set", "train.lr=1e-2"], "holds a run started with other settings"),
    ([*T, "-o", "{ws}/newer_run"], "unsupported run format_version 7"),
    ([*T, "-o", "{ws}/corrupt_run"], "{ws}/corrupt_run/best.eqx: checkpoint files missing or incompatible"),
    ([*T, "-o", "{ws}/run", "--extend", "--steps", "2"], "give --steps larger than its 4"),
    # evaluate
    (["evaluate", "{ws}/run", "--horizons", "1,60"], "60"),
    (["evaluate", "{ws}/run", "--horizons", "abc"], "abc"),
    (["evaluate", "{ws}/run", "--horizons", "-1"], "-1"),
    (["evaluate", "{ws}/run", "--split", "training"], "--split must be one of train, val, test"),
    (["evaluate", "{ws}/d.h5"], "not an fhnn run (no run.json)"),
    (["evaluate", "{ws}/absent"], "not an fhnn run (no run.json)"),
    (["evaluate", "{ws}/corrupt_run"], "{ws}/corrupt_run/best.eqx: checkpoint files missing or incompatible"),
    (["evaluate", "{ws}/newer_run"], "unsupported run format_version 7"),
    (["evaluate", "{ws}/run", "{ws}/foreign.h5"], "not an fhnn data set"),
    # inspect
    (["inspect", "{ws}/sindy"], "inspect needs an fhnn run; a 'sindy' model has no flow or coefficients"),
    (["inspect", "{ws}/absent"], "not an fhnn run (no run.json)"),
    (["inspect", "{ws}/run", "{ws}/nan.h5"], "/train/states has 1 NaN or infinite value(s)"),
    # reproduce
    (["reproduce", "--quick", "-o", "{ws}/rep", "--seeds", "0"], "seeds must be > 0, got 0"),
    # import: tables, body constants, split
    (["import", "{ws}/nocol.csv", "-o", "{ws}/i.h5", *B], "missing column(s) t (have traj_id, time, x, y)"),
    (["import", "{ws}/extra.csv", "-o", "{ws}/i.h5", *B], "unknown column(s) z"),
    (
        ["import", "{ws}/halfvel.csv", "-o", "{ws}/i.h5", *B],
        "column 'vy' is missing: give vx and vy, or neither",
    ),
    (["import", "{ws}/text.csv", "-o", "{ws}/i.h5", *B], "column 'x', row 7: 'two' is not a number"),
    (
        ["import", "{ws}/when.csv", "-o", "{ws}/i.h5", *B],
        "column 't', row 5: 'yesterday' is not a number of seconds or an ISO-8601 date-time",
    ),
    (["import", "{ws}/twice.csv", "-o", "{ws}/i.h5", *B], "column(s) t appear more than once"),
    (
        ["import", "{ws}/zones.csv", "-o", "{ws}/i.h5", *B],
        "column 't': row 1 has a time zone and row 2 has none",
    ),
    (
        ["import", "{ws}/baddate.csv", "-o", "{ws}/i.h5", *B],
        "column 't', row 2: 'soon' is not an ISO-8601 date-time",
    ),
    (["import", "{ws}/inf.csv", "-o", "{ws}/i.h5", *B], "column 'x', trajectory '2', row 12: infinite value"),
    (
        ["import", "{ws}/dup.csv", "-o", "{ws}/i.h5", *B],
        "trajectory '1': rows 6 and 7 have the same time t = 0.1 s",
    ),
    (
        ["import", "{ws}/short.csv", "-o", "{ws}/i.h5", *B],
        "trajectory '9' has 2 sample(s) (row 13); at least 3",
    ),
    (
        ["import", "{ws}/two.csv", "-o", "{ws}/i.h5", *B],
        "the table has 2 trajectory(ies); train, val and test",
    ),
    (["import", "{ws}/empty.csv", "-o", "{ws}/i.h5", *B], "the table has no rows"),
    (["import", "{ws}/gaps.csv", "-o", "{ws}/i.h5", *B], "every row has a missing value"),
    (["import", "{ws}/table.txt", "-o", "{ws}/i.h5", *B], "unknown table type '.txt'"),
    (["import", "{ws}/binary.parquet", "-o", "{ws}/i.h5", *B], "not a readable table"),
    (["import", "{ws}/absent.csv", "-o", "{ws}/i.h5", *B], "absent.csv: no such file"),
    (
        ["import", "{ws}/good.csv", "-o", "{ws}/i.h5", "--mass", "0", "--area", "1"],
        "--mass must be a number > 0",
    ),
    (
        ["import", "{ws}/good.csv", "-o", "{ws}/i.h5", "--mass", "1", "--area", "nan"],
        "--area must be a number > 0",
    ),
    (
        ["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B, "--split", "70/20"],
        "--split must be three percentages",
    ),
    (["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B, "--split", "70/20/20"], "summing to 100"),
    (["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B, "--split", "80/20/0"], "each a share > 0"),
    (
        ["import", "{ws}/good.csv", "-o", "{ws}/missing/i.h5", *B],
        "output folder '{ws}/missing' does not exist",
    ),
    (
        ["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B, "--smoother", "x"],
        "--smoother must be one of auto, spline, kalman",
    ),
    (
        ["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B, "--max-gap", "0"],
        "--max-gap must be auto or a number of seconds > 0, got '0'",
    ),
    (["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B, "--max-gap", "soon"], "--max-gap must be auto or"),
    (
        ["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B, "--max-gap", "0.05"],
        "0 of the table's 3 trajectories keep a piece of at least 3 samples between gaps longer than --max-gap",
    ),
    (
        ["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B, "--outliers", "none"],
        "--outliers must be off or a number of noise levels > 0, got 'none'",
    ),
    (
        ["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B, "--forcing-hold", "step"],
        "--forcing-hold must be one of linear, previous, got 'step'",
    ),
    (
        ["import", "{ws}/forced.csv", "-o", "{ws}/i.h5", *B, "--forcing", "{ws}/force.csv"],
        "the table has Fx, Fy columns: give the known forces there or in --forcing, not both",
    ),
    (
        ["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B, "--forcing", "{ws}/force_late.csv"],
        "the forcing table starts at 0.05 s, after the first sample of trajectory '0' (0 s)",
    ),
    (
        ["import", "{ws}/good.csv", "-o", "{ws}/i.h5", *B, "--forcing", "{ws}/force_short.csv"],
        "the forcing table ends at 0.2 s, before the last sample of trajectory '0' (0.3 s)",
    ),
    (
        [*I, "--forcing", "{ws}/force_twice.csv", "--forcing-hold", "previous"],
        "the held force changes more than once between the samples at 0.1 and 0.2 s of trajectory '0'",
    ),
    (["predict", "{ws}/run", "--duration", "1"], "give --initial x,y,vx,vy or --history TABLE"),
    ([*P, "--history", "{ws}/good.csv"], "give --initial x,y,vx,vy or --history TABLE"),
    (["predict", "{ws}/run", "--duration", "1", "--initial", "1,2,3"], "--initial expects x,y,vx,vy"),
    (["predict", "{ws}/run", "--duration", "1", "--initial", "1,2,a,b"], "--initial expects x,y,vx,vy"),
    (["predict", "{ws}/run", "--duration", "0", "--initial", "0,1,0,0"], "--duration must be > 0 s"),
    ([*P, "--forcing-hold", "step"], "--forcing-hold must be one of linear, previous, got 'step'"),
    ([*P, "--dt", "-1"], "--dt must be > 0 s"),
    ([*P, "--outliers", "-3"], "--outliers must be off or a number of noise levels > 0, got '-3'"),
    ([*P, "--dt", "1e-7"], "is 1e+07 output samples per track; at most 1,000,000"),
    ([*P, "--fit-window", "0"], "--fit-window must be > 0 s"),
    (
        ["predict", "{ws}/run", "--duration", "5", "--initial", "0,1,0,0", "--forcing", "{ws}/force.csv"],
        "the forcing table covers t = 0–1 s; the forecast of trajectory 'initial' needs 0–5 s",
    ),
    ([*P, "--forcing", "{ws}/force_nofy.csv"], "missing column(s) Fy (have t, Fx)"),
    ([*P, "--forcing", "{ws}/force_dup.csv"], "rows 2 and 3 have the same time t = 1 s"),
    (["predict", "{ws}/run", "--duration", "1", "--history", "{ws}/nocol.csv"], "missing column(s) t"),
    (["predict", "{ws}/run", "--duration", "1", "--history", "{ws}/short.csv"], "trajectory '9' has 2"),
    ([*P, "-o", "{ws}/missing/p.csv"], "output folder '{ws}/missing' does not exist"),
    ([*P, "-o", "{ws}/p.txt"], "{ws}/p.txt: give a .csv or .parquet file name"),
    ([*P, "--t0", "nan"], "--t0 must be finite"),
    (["reproduce", "--quick", "-o", "{ws}/rep", "--workers", "0"], "workers"),
    (["reproduce", "--quick", "-o", "{ws}/rep", "--set", "models=fhnn,gru"], "unknown name 'gru' in models"),
    (["reproduce", "--quick", "-o", "{ws}/rep", "--set", "data.n_traj=2"], "n_traj must be >= 3"),
    (["reproduce", "--quick", "-o", "{ws}/rep", "--set", "data.test_duration=5"], "test_duration must cover"),
    (["reproduce", "--quick", "-o", "{ws}/afile"], "output '{ws}/afile' exists and is not a folder"),
    (["reproduce", "--quick", "-o", "{ws}"], "is not empty and holds no reproduction"),
    (["reproduce", "--quick", "-o", "{ws}/missing/rep"], "output folder '{ws}/missing' does not exist"),
    (["reproduce", "--quick", "-o", "{ws}/locked/rep"], "output folder '{ws}/locked' is not writable"),
]


@pytest.mark.parametrize(("args", "message"), CASES, ids=[" ".join(a[:1] + a[-2:]) for a, _ in CASES])
def test_bad_input_is_one_line_exit_2_and_changes_nothing(
    ws: Path, args: list[str], message: str, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    locked = ws / "locked"
    real_access = os.access  # root may write anywhere: the read-only folder is simulated
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == locked else real_access(p, mode))
    before = _snapshot(ws)
    with pytest.raises(SystemExit) as info:
        main([a.format(ws=ws) for a in args])
    err = capsys.readouterr().err
    assert info.value.code == 2, err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert message.format(ws=ws) in err, err
    assert _snapshot(ws) == before


def test_the_matrix_covers_every_command_with_forty_cases() -> None:
    commands = {args[0] for args, _ in CASES}
    assert commands == {
        "simulate",
        "import",
        "info",
        "train",
        "evaluate",
        "inspect",
        "predict",
        "reproduce",
    }
    assert len(CASES) >= 40
