"""The library is what the command line calls: ``fhnn train`` / ``fhnn.train``, ``fhnn inspect`` /
``fhnn.inspect`` and ``fhnn predict`` / ``fhnn.predict`` give the same files and numbers; the
configuration defaults are what ``fhnn train`` trains; a notebook goes from a DataFrame to
coefficients, flow and forecast; and a metric, scenario, model kind or command added in one place
is seen everywhere it belongs."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import typer

import fhnn
from fhnn.api import train as api_train
from fhnn.cli.options import app
from fhnn.data.dataset import read_dataset, write_dataset
from fhnn.data.observation import observe
from fhnn.data.table import read_table, write_table
from fhnn.errors import ConfigError, DataFormatError
from fhnn.evaluation.metrics import METRICS, Metric, register_metric
from fhnn.experiments import figures, tables
from fhnn.models.fhnn import FHNNConfig
from fhnn.models.registry import MODELS, ModelKind
from fhnn.physics.scenarios import SCENARIOS, SteadyVortex, register_scenario, scenario_class
from fhnn.training.ensemble import member_folder
from fhnn.training.run import RunConfig
from fhnn.training.train_config import TrainConfig

from .conftest import run_cli, small_dataset

#: Short phases of every kind (warm-up, Adam, polish) at width 8, as explicit settings.
SHORT = {
    "model.width": 8,
    "train.warmup_steps": 3,
    "train.steps": 4,
    "train.lbfgs_steps": 2,
    "train.lbfgs_pairs": 64,
    "train.val_every": 2,
}
#: An imported table's multi-step training, shortened (and no whole-track fit).
SHORT_IMPORTED = {"model.width": 8, "train.steps": 4, "train.val_every": 2, "train.track_steps": 0}


def _set(settings: dict) -> list[str]:
    return [arg for k, v in settings.items() for arg in ("--set", f"{k}={v}")]


cli = run_cli


def _run_json(folder: Path) -> dict:
    return json.loads((folder / "run.json").read_text())


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("api")
    data = small_dataset("steady_vortex", n_traj=6, duration=2.0, test_duration=3.0)
    write_dataset(data, folder / "data.h5")
    return folder


@pytest.fixture(scope="module")
def table_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tracker's table of a small simulation: positions with 1 mm noise, jittered times."""
    folder = tmp_path_factory.mktemp("table")
    fine = small_dataset("steady_vortex", n_traj=9, duration=3.0, test_duration=3.0, dt=0.01)
    write_table(observe(fine, step=0.05, jitter=0.3, noise=1e-3, seed=1), folder / "track.csv")
    return folder / "track.csv"


def test_the_defaults_are_what_fhnn_train_stores_on_noise_free_data(
    simulated: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """``fhnn train DATA -o RUN`` with no options stores ``FHNNConfig()`` and ``TrainConfig()``
    (the run is saved untrained: what is stored is decided before training)."""

    def save_untrained(runs, labels, dataset, *, say, notes, budget=None):
        for run in runs:
            run.state = run.trainer(dataset).init(run.skeleton())
            run.save()

    monkeypatch.setattr(api_train, "train_runs", save_untrained)
    code, _, err = cli(["train", str(simulated / "data.h5"), "-o", str(tmp_path / "run")], capsys)
    assert code == 0, err
    assert read_dataset(simulated / "data.h5").obs_noise == 0
    stored = _run_json(tmp_path / "run")
    config = RunConfig.from_dict({"model": stored["model_config"], "train": stored["train_config"]})
    assert config.model == FHNNConfig() and config.train == TrainConfig()
    assert config == RunConfig()


def _train_both(data_cli, data_api, out: Path, settings: dict, capsys, *extra: str, **options) -> None:
    code, _, err = cli(
        ["train", str(data_cli), "-o", str(out / "cli"), "-q", *_set(settings), *extra], capsys
    )
    assert code == 0, err
    fhnn.train(data_api, out / "api", settings=settings, progress=False, **options)


def test_cli_and_api_train_write_identical_runs_on_simulated_data(simulated: Path, capsys) -> None:
    _train_both(simulated / "data.h5", simulated / "data.h5", simulated, SHORT, capsys)
    cli_run, api_run = _run_json(simulated / "cli"), _run_json(simulated / "api")
    assert cli_run["step"] == 6 and cli_run["history"]  # it trained
    assert cli_run == api_run


def test_cli_and_api_train_write_identical_ensembles(simulated: Path, capsys) -> None:
    (simulated / "ens").mkdir()
    _train_both(
        simulated / "data.h5",
        simulated / "data.h5",
        simulated / "ens",
        SHORT,
        capsys,
        "--seeds",
        "2",
        seeds=2,
    )
    for seed in (0, 1):
        a = _run_json(member_folder(simulated / "ens" / "cli", seed))
        b = _run_json(member_folder(simulated / "ens" / "api", seed))
        assert a["train_config"]["seed"] == seed and a["train_config"]["bootstrap"] is True
        assert a == b


def test_cli_and_api_train_write_identical_runs_on_an_imported_table(
    table_file: Path, tmp_path: Path, capsys
) -> None:
    argv = ["import", str(table_file), "-o", str(tmp_path / "imp.h5"), "--mass", "10", "--area", "0.1", "-q"]
    code, _, err = cli(argv, capsys)
    assert code == 0, err
    by_cli = read_dataset(tmp_path / "imp.h5")
    by_api = fhnn.import_table(str(table_file), mass=10, area=0.1)
    assert by_cli.extra == by_api.extra
    for split in ("train", "val", "test"):
        np.testing.assert_array_equal(by_cli[split].states, by_api[split].states)
    _train_both(tmp_path / "imp.h5", tmp_path / "imp.h5", tmp_path, SHORT_IMPORTED, capsys)
    a, b = _run_json(tmp_path / "cli"), _run_json(tmp_path / "api")
    assert a["train_config"]["shoot"] > 2 and a["model_config"]["width"] == 8  # the data's settings
    assert a == b


def test_cli_and_api_inspect_and_predict_give_the_same_numbers(simulated: Path, capsys) -> None:
    run = simulated / "cli"
    if not (run / "run.json").exists():  # run alone
        _train_both(simulated / "data.h5", simulated / "data.h5", simulated, SHORT, capsys)
    code, out, err = cli(["inspect", str(run), "--json"], capsys)
    assert code == 0, err
    result = fhnn.inspect(run)
    assert json.loads(out) == json.loads(json.dumps(result.json()))
    assert "c_l" in json.loads(out)["coefficients"]
    code, out, err = cli(
        ["predict", str(run), "--duration", "1", "--initial", "0.5,1.5,0.1,0", "--dt", "0.1"], capsys
    )
    assert code == 0, err
    forecast = fhnn.predict(run, 1.0, initial=[0.5, 1.5, 0.1, 0.0], dt=0.1)
    printed = pd.read_csv(io.StringIO(out))
    assert list(printed.columns) == ["traj_id", "t", "x", "y", "vx", "vy"]
    frame = forecast.to_pandas()
    for column in ("t", "x", "y", "vx", "vy"):
        np.testing.assert_allclose(printed[column], frame[column], rtol=1e-12, atol=0)


def test_cli_and_api_info_describe_the_same_data_set(simulated: Path, capsys) -> None:
    """``fhnn info --json`` prints ``fhnn.info``; it takes the file or the data set read from it,
    and refuses a file that is not a data set in one line."""
    data = simulated / "data.h5"
    code, out, err = cli(["info", str(data), "--json"], capsys)
    assert code == 0, err
    described = fhnn.info(data)
    assert json.loads(out) == json.loads(json.dumps(described, sort_keys=True))
    assert described == fhnn.info(read_dataset(data))
    assert described["scenario"] == "steady_vortex" and described["splits"]["train"]["n_traj"] == 4
    (simulated / "notes.h5").write_text("not HDF5")
    with pytest.raises(DataFormatError, match="notes.h5"):
        fhnn.info(simulated / "notes.h5")
    code, _, err = cli(["info", str(simulated / "notes.h5")], capsys)
    assert code != 0 and len(err.strip().splitlines()) == 1 and "notes.h5" in err


def test_the_notebook_example_runs_from_a_dataframe(table_file: Path, tmp_path: Path) -> None:
    """The README's notebook use: a DataFrame → data → an ensemble of 2 → coefficients with
    intervals, the flow as an xarray.Dataset and a forecast with its band (fast settings)."""
    df = pd.read_csv(table_file)
    data = fhnn.from_table(df, mass=10.0, area=0.1)
    assert data.extra["import"]["source"] == "DataFrame"
    fit = fhnn.train(data, tmp_path / "a", seeds=2, settings=SHORT_IMPORTED, progress=False)
    coefficients = fit.coefficients()
    assert {"c_l", "c_l_lo", "c_l_hi", "sigma"} <= set(coefficients.columns)
    assert (coefficients["c_l_lo"] <= coefficients["c_l_hi"]).all()
    flow = fit.flow()
    assert {"u", "v", "u_lo", "u_hi"} <= set(flow.data_vars) and flow["u"].ndim == 2
    inspection = fit.inspect()
    assert inspection.kind == "ensemble" and inspection.members == 2
    for run in fit.runs:  # each member's figures in its own folder
        assert {run.folder / "flow.png", run.folder / "coefficients.png"} <= set(inspection.written)
        assert (run.folder / "flow.png").stat().st_size > 0
    later = fhnn.load(tmp_path / "a")  # its data set was written beside the runs
    assert later.is_ensemble and later.dataset.extra["import"] == data.extra["import"]
    forecast = later.predict(1.0, history=df[df["traj_id"] == df["traj_id"].iloc[0]], samples=4)
    frame = forecast.to_pandas()
    assert {"x", "x_lo", "x_hi"} <= set(frame.columns) and np.isfinite(frame["x"]).all()


def test_read_table_takes_a_dataframe_as_it_takes_a_file(table_file: Path) -> None:
    from_file, from_frame = read_table(table_file), read_table(pd.read_csv(table_file))
    assert from_file.rows == from_frame.rows and from_file.dropped == from_frame.dropped
    for a, b in zip(from_file.trajectories, from_frame.trajectories, strict=True):
        assert a.traj_id == b.traj_id
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(a.pos, b.pos)


# --- one place to add a metric, a scenario, a model kind, a command ------------------------------


@pytest.fixture
def registries():
    """The metric, scenario and model registries put back as they were after the test."""
    saved = [(registry, dict(registry)) for registry in (METRICS, SCENARIOS, MODELS._kinds)]
    yield
    for registry, before in saved:
        registry.clear()
        registry.update(before)


def test_a_registered_metric_appears_in_results_tables_figures_and_the_cli(
    simulated: Path, registries, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    register_metric(
        Metric(
            "max_pos",
            "max(pos) [m]",
            "max\npos [m]",
            compute=lambda e: float(np.abs(e.err[..., :2]).max()),
            curve=True,
        )
    )
    run = simulated / "cli"
    if not (run / "run.json").exists():  # run alone
        _train_both(simulated / "data.h5", simulated / "data.h5", simulated, SHORT, capsys)
    result = fhnn.evaluate(run, horizons=[1])
    value = result.rows["1"]["max_pos"]
    assert 0 < result.rows["1"]["rmse_pos"] <= value
    code, out, err = cli(["evaluate", str(run), "--horizons", "1"], capsys)
    assert code == 0, err
    assert "max" in out and f"{value:.3g}" in out
    code, out, err = cli(["evaluate", str(run), "--horizons", "1", "--json"], capsys)
    assert json.loads(out)["1"]["max_pos"] == value
    assert tables.metric_label("max_pos") == "max(pos) [m]" and not tables.is_error_metric("max_pos")
    titles: list[str] = []
    monkeypatch.setattr(
        figures, "_save", lambda fig, path, formats: titles.extend(a.get_title() for a in fig.axes)
    )
    curves = {m.name: (np.array([1e-3, 2e-3]), np.zeros(2)) for m in METRICS.values() if m.curve}
    figures.horizon_figure([1.0, 2.0], {"FHNN": curves}, Path("unused"))
    assert "max(pos) [m]" in titles and len(titles) == len(curves)


def test_a_registered_scenario_is_listed_and_simulated(registries, capsys) -> None:
    @register_scenario
    class StrongVortex(SteadyVortex):
        name = "strong_vortex"

    assert scenario_class("strong_vortex") is StrongVortex
    code, out, err = cli(["scenarios"], capsys)
    assert code == 0, err
    assert "strong_vortex" in out
    data = fhnn.simulate("strong_vortex", params={"gamma": 4.0}, n_traj=3, duration=0.5, test_duration=0.5)
    assert data.scenario == "strong_vortex" and np.isfinite(data.train.states).all()
    with pytest.raises(ConfigError, match="already registered"):
        register_scenario(type("Other", (SteadyVortex,), {"name": "strong_vortex"}))


def test_a_registered_model_kind_trains_through_the_cli(
    simulated: Path, tmp_path: Path, registries, capsys
) -> None:
    node = MODELS["node"]
    MODELS.register(
        ModelKind("node2", "Neural ODE 2", "another MLP (s, F) → ṡ", node.config, node.build, node.arguments)
    )
    argv = [
        "train",
        str(simulated / "data.h5"),
        "-o",
        str(tmp_path / "r"),
        "--model",
        "node2",
        "--plan",
        "adam",
    ]
    code, _, err = cli(
        [*argv, "--steps", "2", "--set", "model.width=8", "--set", "train.val_every=1", "-q"], capsys
    )
    assert code == 0, err
    assert _run_json(tmp_path / "r")["model"] == "node2"
    assert fhnn.evaluate(tmp_path / "r", horizons=[1]).rows["1"]["rmse_pos"] > 0
    with pytest.raises(ConfigError, match="already registered"):
        MODELS.register(node)


def test_a_command_is_one_function_on_the_app(monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    monkeypatch.setattr(app, "registered_commands", list(app.registered_commands))

    @app.command()
    def hello(name: str = typer.Option("world", help="Whom to greet.")) -> None:
        """Say hello."""
        typer.echo(f"hello {name}")

    code, out, _ = cli(["--help"], capsys)
    assert code == 0 and "hello" in out and "Say hello." in out
    code, out, _ = cli(["hello", "--name", "fhnn"], capsys)
    assert code == 0 and out.strip() == "hello fhnn"
