"""Shared fixtures. Importing fhnn switches JAX to float64 for the whole test session.

The test session keeps a persistent JAX compilation cache in a temporary folder (removed at
exit; shared by the xdist workers): the many trainers the tests build compile the same programs
again (a resumed run, the straight run it is compared with), and a cache hit gives the same
executable, so results are unchanged and the suite spends less time in XLA. Commands started by the tests (in-process or as
subprocesses) use the same folder through ``$FHNN_JAX_CACHE``.
"""

# ruff: noqa: E402  (XLA_FLAGS is set before anything imports JAX)

from __future__ import annotations

import os

#: The flag the package never sets (below): the test of bitwise agreement between a stored
#: program and a plain jitted one (``tests/test_executables.py``), which holds for the fusion
#: emitters, runs its processes without it.
TEST_ONLY_XLA_FLAG = "--xla_cpu_use_fusion_emitters=false"
#: The suite is mostly compilation (hundreds of small programs, each run a few times), so it
#: compiles as ``fhnn reproduce --quick``'s workers do (``fast_compile``: LLVM optimisation level
#: 0): the same programs, run more slowly; the whole suite took 763 s against 981 s, back to back
#: on 2 cores. On top of that, XLA's CPU fusion emitters are off (the older loop emitter): a
#: two-step whole-track fit, most of it compilation, took 43 s against 59 s without a cache, and
#: its validation loss moved in the last bit only. Set before JAX starts its backend (nothing has
#: imported JAX yet), here and in the subprocesses the tests start (they inherit it); checked to
#: hold the package's flags below.
#: And XLA's CPU runtime runs each operation on one thread (``--xla_cpu_multi_thread_eigen=false``):
#: the two xdist workers already fill the two cores, and each worker's operations are small, so
#: a thread pool per operation only contends; ``test_track_fit.py`` and ``test_planar_controls.py``
#: took 145 s against 159 s with it, back to back on 2 cores (2026-12-06).
#: And each program is code-generated as one LLVM module
#: (``--xla_cpu_parallel_codegen_split_count=1``; XLA splits it into up to 32 parts compiled in
#: parallel): with both cores busy, the parts only add overhead; the suite took 868 s (927 s in a
#: second run) against 1,062 s, back to back on 2 cores (``docs/design/layout.md``).
TEST_XLA_FLAGS = (
    "--xla_backend_optimization_level=0 --xla_cpu_multi_thread_eigen=false "
    f"--xla_cpu_parallel_codegen_split_count=1 {TEST_ONLY_XLA_FLAG}"
)
if TEST_XLA_FLAGS not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {TEST_XLA_FLAGS}".strip()

# isort: off
import fhnn  # noqa: F401  (before the rest: float64, and Equinox's runtime checks as NaN)

# isort: on

import atexit
import shutil
import tempfile
from pathlib import Path

import equinox as eqx
import jax
import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from fhnn.data.dataset import Dataset, write_dataset
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.experiments.executors import FAST_COMPILE_FLAGS
from fhnn.models.fhnn import FHNNConfig
from fhnn.physics.scenarios import SCENARIOS, get_scenario
from fhnn.runtime import CACHE_ENV, use_compilation_cache
from fhnn.training.plans import PAPER_FHNN, PAPER_TRAIN, PLANS
from fhnn.training.run import RunConfig
from fhnn.training.train_config import TrainConfig

pytest_plugins = ["tests.crash_retry"]

#: Under pytest-xdist the controller makes the folder and its workers inherit it, so a program one
#: worker compiled the other loads (both compile the same small FHNN programs); the controller
#: removes it at exit. Without xdist, or if the controller never read this file, each process has
#: its own.
_SHARED = "FHNN_TEST_JAX_CACHE"
if os.environ.get("PYTEST_XDIST_WORKER") and os.path.isdir(os.environ.get(_SHARED, "")):
    _CACHE = os.environ[_SHARED]
else:
    _CACHE = tempfile.mkdtemp(prefix="fhnn-test-jax-cache-")
    atexit.register(shutil.rmtree, _CACHE, ignore_errors=True)
    os.environ[_SHARED] = _CACHE
assert set(FAST_COMPILE_FLAGS.split()) <= set(TEST_XLA_FLAGS.split()), (
    "the tests compile as fast_compile does"
)
use_compilation_cache(_CACHE)
os.environ[CACHE_ENV] = _CACHE

# Property tests (tests/test_properties.py): 200 examples per property by default; the nightly
# profile draws 5,000 (HYPOTHESIS_PROFILE=nightly). No deadline: the first example compiles.
settings.register_profile(
    "default", max_examples=200, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile(
    "nightly", max_examples=5000, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))

#: The longest tests (half a minute to 80 s each on 2 cores), run first, so that the two xdist
#: workers finish together rather than one waiting on a long test that started last.
LONGEST_FIRST = (
    "test_import.py::test_train_evaluate_inspect_on_imported_data",
    "test_faults.py::test_reproduction_killed_three_times",
    "test_time_budget.py::test_max_time_bounds_an_ensemble",
    "test_track_fit.py::test_it_is_the_last_phase",
    "test_faults.py::test_training_killed_in_every_phase",
    "test_track_fit.py::test_a_matrix_free_step_is_the_dense_gauss_newton_step",
    "test_planar_controls.py::test_training_learns_the_map",
    "test_planar.py::test_the_turning_commands_simulate_train_and_evaluate",
    "test_lab_tables.py::test_predict_reads_a_lab_history",
    "test_examples.py::test_own_data_example",
    "test_executables.py::test_a_new_process_trains_from_the_stored_programs",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    def rank(item: pytest.Item) -> int:
        return next((i for i, name in enumerate(LONGEST_FIRST) if name in item.nodeid), len(LONGEST_FIRST))

    items.sort(key=rank)


#: Small data sets: every split present, short trajectories, fast to simulate.
SMALL = dict(n_traj=6, duration=3.0, test_duration=6.0)


def arrays(tree: object) -> list:
    """The array leaves of a model or state, in order."""
    return jax.tree_util.tree_leaves(eqx.filter(tree, eqx.is_array))


def small_dataset(name: str, **overrides: object) -> Dataset:
    scenario = get_scenario(name)
    config = SimulationConfig.for_scenario(scenario, **{**SMALL, **overrides})
    return simulate_dataset(scenario, config)


@pytest.fixture(scope="session", params=sorted(SCENARIOS))
def scenario_dataset(request: pytest.FixtureRequest) -> Dataset:
    """A small simulated data set of every scenario (with actuation where the scenario has it)."""
    return small_dataset(request.param)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


# The paper's settings (the ``adam`` plan), which were the configuration defaults when these tests
# were written: the tests below that build configurations by hand start from them, so that their
# runs train as they always have (the defaults are now what ``fhnn train`` trains).


def paper_train(**fields: object) -> TrainConfig:
    """The paper's training configuration (``PLANS["adam"].train``) with ``fields`` changed."""
    return PAPER_TRAIN.replace(**fields)


def paper_fhnn(**fields: object) -> FHNNConfig:
    """The paper's FHNN configuration (width 64, windows unweighted) with ``fields`` changed."""
    return FHNNConfig(**{**PAPER_FHNN, **fields})


#: The paper's run configuration (FHNN and training of the ``adam`` plan).
PAPER_RUN = RunConfig().with_settings(PLANS["adam"].settings("fhnn"))


def run_cli(argv: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str, str]:
    """``fhnn ARGV`` in this process: its exit code, standard output and standard error."""
    from fhnn.cli.app import main

    with pytest.raises(SystemExit) as info:
        main(argv)
    captured = capsys.readouterr()
    return info.value.code, captured.out, captured.err


@pytest.fixture(scope="module")
def data_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small ``steady_vortex`` data set written once per test module (``d.h5``)."""
    folder = tmp_path_factory.mktemp("data")
    return write_dataset(
        small_dataset("steady_vortex", n_traj=6, duration=2.0, test_duration=3.0), folder / "d.h5"
    )
