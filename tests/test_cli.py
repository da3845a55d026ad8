"""The command line: simulate and info, and one-line errors with exit status 2 on bad input."""

import json
import math
import shutil
import subprocess
import sys

import h5py
import pytest

from fhnn.cli.app import main


def run(argv, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    captured = capsys.readouterr()
    return info.value.code, captured.out, captured.err


def test_simulate_then_info(tmp_path, capsys):
    out = tmp_path / "sv.h5"
    code, stdout, _ = run(
        [
            "simulate",
            "steady_vortex",
            "-o",
            str(out),
            "--n-traj",
            "5",
            "--duration",
            "2",
            "--test-duration",
            "3",
            "--seed",
            "3",
            "-p",
            "gamma=4.5",
            "-q",
        ],
        capsys,
    )
    assert code == 0 and out.exists() and stdout == ""
    code, stdout, _ = run(["info", str(out), "--json"], capsys)
    assert code == 0
    summary = json.loads(stdout)
    assert summary["scenario"] == "steady_vortex"
    assert summary["scenario_params"]["gamma"] == 4.5
    assert summary["seed"] == 3
    assert {k: v["n_traj"] for k, v in summary["splits"].items()} == {"train": 3, "val": 1, "test": 1}
    assert summary["splits"]["test"]["n_times"] == 61
    lo, hi = summary["splits"]["train"]["coverage"]["r"]
    assert 0 < lo <= hi
    lo, hi = summary["splits"]["train"]["coverage"]["sigma"]
    assert 1e-6 <= lo <= hi
    code, stdout, _ = run(["info", str(out)], capsys)
    assert code == 0 and "steady_vortex" in stdout and "σ [m/s]" in stdout


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["simulate", "vortex"], "unknown scenario 'vortex'; available: steady_vortex"),
        (
            ["simulate", "steady_vortex", "-p", "gama=2"],
            "unknown parameter 'gama' for scenario 'steady_vortex' (did you mean 'gamma'?)",
        ),
        (
            ["simulate", "steady_vortex", "-p", "mass=-1"],
            "scenario 'steady_vortex': mass must be > 0, got -1.0",
        ),
        (["simulate", "steady_vortex", "-p", "mass"], "--param expects NAME=VALUE, got 'mass'"),
        (["simulate", "steady_vortex", "--dt", "0"], "simulation: dt must be > 0, got 0.0"),
        (["simulate", "steady_vortex", "--dt", "-0.1"], "simulation: dt must be > 0, got -0.1"),
        (["simulate", "steady_vortex", "--n-traj", "0"], "simulation: n_traj must be >= 1, got 0"),
        (["simulate", "steady_vortex", "--n-traj", "abc"], "Invalid value for '--n-traj'"),
        (
            ["simulate", "steady_vortex", "--actuation", "sometimes"],
            "simulation.actuation must be one of 'none', 'random', got 'sometimes'",
        ),
        (["simulate", "steady_vortex", "--frobnicate"], "No such option: --frobnicate"),
    ],
)
def test_bad_simulate_arguments(tmp_path, capsys, args, message):
    out = tmp_path / "x.h5"
    code, _, stderr = run([*args, "-o", str(out)] if "-o" not in args else args, capsys)
    assert code == 2
    assert stderr.startswith("error: ") and stderr.count("\n") == 1, stderr
    assert message in stderr
    assert list(tmp_path.iterdir()) == []


def test_output_in_missing_folder(tmp_path, capsys):
    code, _, stderr = run(["simulate", "steady_vortex", "-o", str(tmp_path / "no" / "x.h5")], capsys)
    assert code == 2 and stderr == f"error: output folder '{tmp_path / 'no'}' does not exist\n"


def test_info_on_bad_files(tmp_path, capsys):
    (tmp_path / "cut.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 50)
    with h5py.File(tmp_path / "foreign.h5", "w") as f:
        f["x"] = 1
    for name, message in (
        ("cut.h5", "not a readable HDF5 file"),
        ("foreign.h5", "not an fhnn data set"),
        ("absent.h5", "no such file"),
    ):
        code, _, stderr = run(["info", str(tmp_path / name)], capsys)
        assert code == 2 and message in stderr and stderr.count("\n") == 1


@pytest.mark.skipif(shutil.which("fhnn") is None, reason="console script not installed")
def test_console_script(tmp_path):
    done = subprocess.run(
        ["fhnn", "simulate", "nope", "-o", str(tmp_path / "x.h5")], capture_output=True, text=True
    )
    assert done.returncode == 2
    assert done.stderr.strip().startswith("error: unknown scenario 'nope'")
    done = subprocess.run([sys.executable, "-m", "fhnn.cli.app", "--help"], capture_output=True, text=True)
    assert done.returncode == 0 and "simulate" in done.stdout


def test_json_output_of_an_infinite_error_is_strict_json_null() -> None:
    """A diverged rollout's error is infinite; ``--json`` writes it as null, never ``Infinity``."""
    from fhnn.api.evaluate import finite_or_null

    metrics = {"1": {"rmse_pos": math.inf, "ade": 0.5, "mse_pos": math.nan}, "runs": [1.0, -math.inf]}
    text = json.dumps(finite_or_null(metrics), allow_nan=False)

    def refuse(token: str) -> None:
        raise AssertionError(f"non-standard JSON token {token}")

    assert json.loads(text, parse_constant=refuse) == {
        "1": {"rmse_pos": None, "ade": 0.5, "mse_pos": None},
        "runs": [1.0, None],
    }


def test_the_command_line_starts_without_the_functions_it_calls() -> None:
    """``fhnn --help`` and every command load the command line without the API's modules (each
    command imports the function it calls when it runs) or the libraries only they need."""
    code = (
        "import sys, fhnn.cli.app\n"
        "print(' '.join(sorted(m for m in sys.modules if m.startswith(('fhnn.api.', 'pandas', "
        "'matplotlib', 'scipy.stats', 'xarray')))))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["fhnn.api.defaults", "fhnn.api.report"]
