"""A lab's own tables: its column names (``--columns``), its time unit (``--time-unit``), and an
import summary that says how many samples there are and where the glitches were."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import fhnn
from fhnn.data.dataset import read_dataset
from fhnn.data.observation import observe
from fhnn.data.table import parse_columns, write_table
from fhnn.errors import ConfigError

from .conftest import run_cli, small_dataset

#: The lab's names of our columns.
LAB = {"traj_id": "track", "t": "time", "x": "pos_x", "y": "pos_y", "Fx": "thrust_x", "Fy": "thrust_y"}
MAPPING = ",".join(f"{ours}={theirs}" for ours, theirs in LAB.items())


cli = run_cli


@pytest.fixture(scope="module")
def tables(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The same observations three ways: our columns in seconds, the lab's columns in seconds,
    and our columns in milliseconds; one position of track 2 at sample 30 is a 0.5 m glitch."""
    folder = tmp_path_factory.mktemp("lab")
    fine = small_dataset("steady_vortex", n_traj=6, duration=3.0, test_duration=3.0, dt=0.01)
    table = observe(fine, step=0.05, jitter=0.3, noise=1e-3, seed=2)
    rows = np.flatnonzero(table["traj_id"] == 2)
    glitch = rows[np.argsort(table["t"][rows])[30]]
    table["x"][glitch] += 0.5
    write_table(table, folder / "ours.csv")
    write_table({LAB.get(c, c): v for c, v in table.items()}, folder / "lab.csv")
    write_table({**table, "t": table["t"] * 1e3}, folder / "ms.csv")
    (folder / "glitch.txt").write_text(repr(float(table["t"][glitch])))
    return folder


def _import(table: Path, out: Path, capsys, *extra: str) -> tuple[int, str, str]:
    return cli(["import", str(table), "-o", str(out), "--mass", "10", "--area", "0.1", *extra], capsys)


def test_a_lab_table_imports_with_its_column_names(tables: Path, tmp_path: Path, capsys) -> None:
    code, _, err = _import(tables / "lab.csv", tmp_path / "plain.h5", capsys)
    assert code == 2 and err.count("\n") == 1 and "missing column(s) traj_id, t, x, y" in err
    assert not (tmp_path / "plain.h5").exists()
    code, _, err = _import(tables / "lab.csv", tmp_path / "lab.h5", capsys, "--columns", MAPPING, "-q")
    assert code == 0, err
    code, _, err = _import(tables / "ours.csv", tmp_path / "ours.h5", capsys, "-q")
    assert code == 0, err
    lab, ours = read_dataset(tmp_path / "lab.h5"), read_dataset(tmp_path / "ours.h5")
    for split in ("train", "val", "test"):
        np.testing.assert_array_equal(lab[split].states, ours[split].states)
        np.testing.assert_array_equal(lab[split].forces, ours[split].forces)
    # in Python, from a DataFrame with the lab's names
    frame = fhnn.from_table(pd.read_csv(tables / "lab.csv"), mass=10, area=0.1, columns=LAB)
    np.testing.assert_array_equal(frame.train.states, ours.train.states)


@pytest.mark.parametrize(
    ("columns", "message"),
    [
        ("traj_id=track,t", "--columns expects NAME=COLUMN"),
        ("id=track", "'id' is not a column of fhnn's"),
        ("x=pos_x,y=pos_x", "the table's column 'pos_x' is mapped twice"),
        ("traj_id=track,t=clock", "no column 'clock' (for t)"),
    ],
)
def test_a_bad_column_mapping_is_one_line_and_writes_nothing(
    tables: Path, tmp_path: Path, capsys, columns: str, message: str
) -> None:
    code, out, err = _import(tables / "lab.csv", tmp_path / "x.h5", capsys, "--columns", columns)
    assert code == 2 and message in err and err.count("\n") == 1 and out == ""
    assert not (tmp_path / "x.h5").exists()


def test_parse_columns_takes_text_or_a_mapping() -> None:
    assert parse_columns("traj_id = track, t=time") == {"traj_id": "track", "t": "time"}
    assert parse_columns(LAB) == LAB and parse_columns(None) == {} == parse_columns("")
    with pytest.raises(ConfigError, match="t is mapped twice"):
        parse_columns("t=a,t=b")


def test_times_in_milliseconds_are_read_with_their_unit_or_warned_of(
    tables: Path, tmp_path: Path, capsys
) -> None:
    code, _, err = _import(tables / "ms.csv", tmp_path / "ms.h5", capsys, "--time-unit", "ms", "-q")
    assert code == 0, err and "warning" not in err
    code, _, err = _import(tables / "ours.csv", tmp_path / "s.h5", capsys, "-q")
    a, b = read_dataset(tmp_path / "ms.h5"), read_dataset(tmp_path / "s.h5")
    np.testing.assert_allclose(a.train.t, b.train.t, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(a.train.states, b.train.states, rtol=1e-9, atol=1e-12)
    assert a.extra["import"]["time_unit"] == "ms" and a.extra["import"]["warnings"] == []
    # read as seconds: steps of ~50 "s" at ~1e-4 "m/s" are said to look like milliseconds
    code, _, err = _import(tables / "ms.csv", tmp_path / "as_s.h5", capsys, "-q")
    assert code == 0 and "warning: the median step is" in err and "--time-unit" in err
    with pytest.warns(UserWarning, match="--time-unit"):
        fhnn.import_table(str(tables / "ms.csv"), mass=10, area=0.1)
    code, _, err = _import(tables / "ours.csv", tmp_path / "bad.h5", capsys, "--time-unit", "fortnight")
    assert code == 2 and "--time-unit must be one of s, ms, us, min, h" in err
    assert not (tmp_path / "bad.h5").exists()


def test_the_import_summary_counts_samples_and_locates_the_glitch(
    tables: Path, tmp_path: Path, capsys
) -> None:
    code, out, err = _import(tables / "ours.csv", tmp_path / "d.h5", capsys)
    assert code == 0, err
    data = read_dataset(tmp_path / "d.h5")
    record = data.extra["import"]
    assert record["outliers_dropped"] == 1
    (traj, time), glitch = record["outliers_at"][0], float((tables / "glitch.txt").read_text())
    assert traj == "2" and time == pytest.approx(glitch, abs=1e-12)
    assert f"trajectory '2' at t = {glitch:.6g} s" in out
    total = int(np.sum(data.train.sample_counts))
    info = fhnn.info(data)
    assert info["splits"]["train"]["samples"] == total > info["splits"]["train"]["n_times"]
    assert f"dt {float(data.dt):.4g} s" in out and "e-1" not in out.splitlines()[0]


def test_predict_reads_a_lab_history_with_the_mapping(tables: Path, tmp_path: Path, capsys) -> None:
    code, _, err = _import(tables / "lab.csv", tmp_path / "lab.h5", capsys, "--columns", MAPPING, "-q")
    assert code == 0, err
    argv = ["train", str(tmp_path / "lab.h5"), "-o", str(tmp_path / "run"), "--plan", "adam", "--steps", "2"]
    code, _, err = cli([*argv, "--set", "model.width=8", "--set", "train.val_every=1", "-q"], capsys)
    assert code == 0, err
    lab = pd.read_csv(tables / "lab.csv")
    history = lab[(lab["track"] == 1) & (lab["time"] <= 1.5)]
    history.to_csv(tmp_path / "history.csv", index=False)
    base = ["predict", str(tmp_path / "run"), "--duration", "0.5", "--dt", "0.1", "--samples", "0"]
    code, out, err = cli([*base, "--history", str(tmp_path / "history.csv"), "--columns", MAPPING], capsys)
    assert code == 0, err
    lines = out.strip().splitlines()
    assert lines[0] == "traj_id,t,x,y,vx,vy" and len(lines) == 7 and lines[1].startswith("1,")
    ours = history.rename(columns={v: k for k, v in LAB.items()})
    same = fhnn.predict(tmp_path / "run", 0.5, history=ours, dt=0.1, samples=0).rows()
    assert same == lines
