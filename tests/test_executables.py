"""Executables kept on disk (:mod:`fhnn.executables`): bitwise the function's results, loaded by a
later process without tracing, keyed on everything that fixes the program, never trusted when
damaged, and bypassed for what has no stable key."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import fhnn.executables as executables
from fhnn.data.dataset import write_dataset
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.executables import StoredProgram
from fhnn.physics.scenarios import get_scenario

from .conftest import TEST_ONLY_XLA_FLAG

TRACES: list[int] = []


@dataclass(frozen=True)
class Scale:
    factor: float


@eqx.filter_jit
def program(model: eqx.nn.MLP, x: jax.Array, scale: Scale, flip: bool) -> tuple:
    TRACES.append(1)
    y = jax.vmap(model)(x) * scale.factor
    return model, {"y": -y if flip else y, "rows": x.shape[0], "activation": model.activation}


@pytest.fixture
def store(tmp_path, monkeypatch):
    """Executables go to ``tmp_path``; the process's memo starts empty."""
    monkeypatch.setattr(executables, "store_folder", lambda: tmp_path)
    monkeypatch.setattr(executables, "_MEMO", {})
    return tmp_path


def new_process(monkeypatch) -> None:
    """What a new process sees: nothing in memory, the files on disk."""
    monkeypatch.setattr(executables, "_MEMO", {})


def arguments(rows=5, factor=2.0, flip=False):
    model = eqx.nn.MLP(3, 2, 4, 2, activation=jnp.tanh, key=jax.random.PRNGKey(0))
    x = jnp.asarray(np.random.default_rng(1).normal(size=(rows, 3)))
    return model, x, Scale(factor), flip


def assert_same(a, b) -> None:
    la, ta = jax.tree.flatten(a)
    lb, tb = jax.tree.flatten(b)
    assert ta == tb
    for x, y in zip(la, lb, strict=True):
        if eqx.is_array(x):
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
        else:
            assert x == y


def test_bitwise_the_functions_results_and_loaded_untraced_by_a_later_process(store, monkeypatch):
    args = arguments()
    stored = StoredProgram(program)
    out = stored(*args)
    assert_same(out, program(*args))
    assert out[1]["activation"] is jnp.tanh  # a non-array output is the input's object
    assert (stored.stored, stored.loaded) == (1, 0) and len(list(store.iterdir())) == 1
    new_process(monkeypatch)
    before = len(TRACES)
    again = StoredProgram(program)
    assert_same(again(*args), out)
    assert len(TRACES) == before  # read from disk: nothing traced
    assert (again.stored, again.loaded) == (0, 1)
    # same signature again in this process: served from memory, no file read
    third = StoredProgram(program)
    assert_same(third(*args), out)
    assert (third.stored, third.loaded) == (0, 0) and len(TRACES) == before


@pytest.mark.parametrize(
    "change", [{"rows": 6}, {"factor": 3.0}, {"flip": True}], ids=["shape", "static-value", "static-flag"]
)
def test_each_part_of_the_signature_is_in_the_key(store, monkeypatch, change):
    base = StoredProgram(program)
    base(*arguments())
    new_process(monkeypatch)
    other = StoredProgram(program)
    args = arguments(**change)
    assert_same(other(*args), program(*args))
    assert (other.stored, other.loaded) == (1, 0) and len(list(store.iterdir())) == 2


@eqx.filter_jit
def accumulate(x: jax.Array, state: dict, scale: jax.Array) -> tuple:
    return x + scale * state["m"], {"m": state["m"] * 2.0, "n": state["n"] + 1}


def test_donated_arguments_are_given_to_the_outputs_bitwise_and_the_others_kept(store, monkeypatch):
    def fresh():
        return jnp.arange(4.0), {"m": jnp.full(4, 0.5), "n": jnp.asarray(3)}, jnp.asarray(1.5)

    expected = accumulate(*fresh())
    for loaded in (False, True):  # compiled here, then read from disk by a new process
        if loaded:
            new_process(monkeypatch)
        donating = StoredProgram(accumulate, donate=(0, 1))
        x, state, scale = fresh()
        out = donating(x, state, scale)
        assert_same(out, expected)
        assert (donating.stored, donating.loaded) == ((0, 1) if loaded else (1, 0))
        assert x.is_deleted() and state["m"].is_deleted() and state["n"].is_deleted()
        assert not scale.is_deleted()  # not donated: still the caller's
        assert_same(donating(*out, scale), accumulate(*expected, scale))  # outputs fed back
    # called as it is (no store): nothing donated
    monkeypatch.setattr(executables, "store_folder", lambda: None)
    x, state, scale = fresh()
    assert_same(StoredProgram(accumulate, donate=(0, 1))(x, state, scale), expected)
    assert not x.is_deleted()


def test_a_damaged_file_is_discarded_and_compiled_again(store, monkeypatch, caplog):
    args = arguments()
    StoredProgram(program)(*args)
    (path,) = store.iterdir()
    path.write_bytes(b"not an executable")
    new_process(monkeypatch)
    again = StoredProgram(program)
    with caplog.at_level(logging.WARNING, logger="fhnn.executables"):
        assert_same(again(*args), program(*args))
    assert f"discarding stored executable {path.name}" in caplog.text
    assert (again.stored, again.loaded) == (1, 0) and path.read_bytes() != b"not an executable"


def test_what_has_no_stable_key_is_called_as_it_is(store, tmp_path, monkeypatch):
    offset = 0.5

    def shifted(x):  # a closure: its cell's value would not be in the key
        return x + offset

    @eqx.filter_jit
    def apply(f, x):
        return f(x)

    x = jnp.arange(3.0)
    unkeyed = StoredProgram(apply)
    tries = []
    prepare = StoredProgram._prepare
    monkeypatch.setattr(StoredProgram, "_prepare", lambda self, *a: tries.append(1) or prepare(self, *a))
    for other in (x, x + 1.0, jnp.arange(4.0), x):  # the signature's failure is remembered
        np.testing.assert_array_equal(np.asarray(unkeyed(shifted, other)), np.asarray(other + 0.5))
    assert unkeyed.stored == 0 and list(store.iterdir()) == [] and len(tries) == 2
    for k in (1.0, 2.0):  # a program that is itself a closure: two of one name compute differently

        @eqx.filter_jit
        def scaled(x, k=k):
            return x * k + offset

        np.testing.assert_array_equal(np.asarray(StoredProgram(scaled)(x)), np.asarray(x * k + 0.5))
    assert list(store.iterdir()) == []
    inner = StoredProgram(program)  # inside a traced program its arguments are tracers
    args = arguments()
    traced = jax.jit(lambda x: inner(args[0], x, args[2], False)[1]["y"])(args[1])
    np.testing.assert_array_equal(np.asarray(traced), np.asarray(program(*args)[1]["y"]))
    assert inner.stored == 0 and list(store.iterdir()) == []
    monkeypatch.setattr(executables, "store_folder", lambda: None)  # no compilation cache folder
    plain = StoredProgram(program)
    assert_same(plain(*arguments()), program(*arguments()))
    assert plain.stored == 0 and list(store.iterdir()) == []


SCRIPT = """
import hashlib, json, sys
import jax, numpy as np
import equinox as eqx
from fhnn.runtime import use_compilation_cache
use_compilation_cache(sys.argv[1])
from fhnn.data.dataset import read_dataset
from fhnn.models.fhnn import FHNNConfig
from fhnn.models.registry import MODELS
from fhnn.training.trainer import TrainConfig, Trainer
data = read_dataset(sys.argv[2])
kind = MODELS["fhnn"]
model = kind.make(FHNNConfig(width=8, depth=2), kind.arguments(data), 0)
tr = Trainer(TrainConfig(steps=3, val_every=3, batch_size=8, lbfgs_steps=5, lbfgs_pairs=16), data.train, data.val)
state = tr.polish(tr.run(tr.init(model)))
h = hashlib.sha256()
for leaf in jax.tree.leaves(eqx.filter(state.model, eqx.is_array)):
    h.update(np.asarray(leaf).tobytes())
programs = tr._programs.values()
from fhnn.models.base import _SOLVE
ro = state.model.rollout(data.test)
rollout = hashlib.sha256(np.asarray(ro.states).tobytes() + np.asarray(ro.ok).tobytes()).hexdigest()
print(json.dumps({"stored": sum(p.stored for p in programs), "loaded": sum(p.loaded for p in programs),
                  "weights": h.hexdigest(), "rollout": [_SOLVE.stored, _SOLVE.loaded, rollout]}))
"""


def test_a_new_process_trains_from_the_stored_programs_to_the_same_weights(tmp_path):
    """Two processes (different hash seeds) train the same small run (Adam, then an L-BFGS polish,
    whose stored program takes its state by donation) and roll the result out over the test split
    with one cache folder: the first compiles and stores the trainer's programs and the rollout,
    the second loads every one of them, and both end at the weights and rollout of a third process
    that runs the plain jitted programs (no store, nothing donated)."""
    sc = get_scenario("steady_vortex")
    data = tmp_path / "data.h5"
    write_dataset(
        simulate_dataset(
            sc, SimulationConfig.for_scenario(sc, n_traj=4, duration=1.0, test_duration=1.0, dt=0.1)
        ),
        data,
    )
    cache = tmp_path / "cache"
    runs = []
    for seed, store in (("1", "on"), ("2", "on"), ("3", "off")):
        env = {**os.environ, "PYTHONHASHSEED": seed, executables.STORE_ENV: store}
        env["XLA_FLAGS"] = " ".join(f for f in env.get("XLA_FLAGS", "").split() if f != TEST_ONLY_XLA_FLAG)
        done = subprocess.run(
            [sys.executable, "-c", SCRIPT, str(cache), str(data)], capture_output=True, text=True, env=env
        )
        assert done.returncode == 0, done.stderr[-2000:]
        runs.append(json.loads(done.stdout.splitlines()[-1]))
    first, second, plain = runs
    assert first["stored"] >= 3 and first["loaded"] == 0  # the Adam chunk, validation, L-BFGS
    rollout = first["rollout"][2]
    assert first["rollout"] == [1, 0, rollout]
    assert second == {
        "stored": 0,
        "loaded": first["stored"],
        "weights": first["weights"],
        "rollout": [0, 1, rollout],
    }
    assert plain == {"stored": 0, "loaded": 0, "weights": first["weights"], "rollout": [0, 0, rollout]}
    assert len(list(Path(cache, executables.FOLDER).iterdir())) == first["stored"] + 1


def test_the_store_follows_the_cache_folder_and_can_be_turned_off(tmp_path, monkeypatch):
    before = jax.config.jax_compilation_cache_dir
    try:
        jax.config.update("jax_compilation_cache_dir", str(tmp_path))
        monkeypatch.delenv(executables.STORE_ENV, raising=False)
        assert executables.store_folder() == tmp_path / executables.FOLDER
        monkeypatch.setenv(executables.STORE_ENV, " OFF ")
        assert executables.store_folder() is None
        monkeypatch.setenv(executables.STORE_ENV, "")
        assert executables.store_folder() == tmp_path / executables.FOLDER
        jax.config.update("jax_compilation_cache_dir", None)
        assert executables.store_folder() is None
    finally:
        jax.config.update("jax_compilation_cache_dir", before)
