"""Where training time goes, and how it compares with its anchors. Prints ratios measured in one run.

1. Time per step of each phase on ``solid_body_vortex`` (64 trajectories): an Adam step at batch 256
   with and without the flow penalty (its annealed weight is zero for the second half of the steps,
   where the trainer runs a second compiled step without it), the gradient of each loss term alone
   (where a step's time goes), and a quasi-Newton iteration's objective and gradient on the L-BFGS
   pair set, for the warm-up part (linear flow and coefficients, no stream MLP) and for the whole
   model.
2. Compilation of the Adam step: a first job, a second job with the same shapes in the same process
   (the trainer's programs are module-level, so nothing is traced again), and a second job in a new
   process sharing the compilation cache folder (what every ``fhnn`` command uses): the step as the
   trainer runs it, read untraced from the executable the first job stored
   (:mod:`fhnn.executables`), against the plain jitted step, traced and looked up in JAX's
   persistent cache. Then a rollout's compilation in a first and a second process: stored
   (:mod:`fhnn.executables`), traced, and traced under Equinox's default runtime checks.
3. Seeds trained as one program: ``N`` models stacked and one ``vmap``-ed chunk of Adam steps (the
   program the trainer runs), against ``N`` sequential chunks (throughput ratio, per step), for
   the step with every loss term and the flow penalty and for the step ``fhnn train`` runs (the
   default plan's loss and width); and one model at ``N`` times the batch, which shows how far
   the step is compute-bound.
4. With ``--targets``: time to the accuracy targets (``benchmarks/fhnn_targets.py``: the default
   plan, as ``fhnn train`` runs it) against this project's earlier times (296 s
   ``solid_body_vortex``, 495 s ``steady_vortex``) and the authors' JAX code (1,978 s for its
   18,000 steps; RMSE(pos) 1.2e-4 m at 1 s).
5. With ``--ensemble``: ``fhnn train --seeds N`` end to end on ``steady_vortex`` (the default plan:
   warm-up discarded, Adam, polish), the members' Adam phases as one program against the members
   one after another (:func:`fhnn.training.ensemble.train_members`).

Usage::

    python benchmarks/training_speed.py [--seeds 3] [--targets] [--out DIR]
                                        [--ensemble [--ensemble-train JSON]] [--ensemble-only]
                                        [--rollout-only]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from _common import dataset, printed_result, seconds_per_call

import fhnn
from fhnn.executables import STORE_ENV, StoredProgram
from fhnn.models.registry import MODELS
from fhnn.runtime import use_compilation_cache
from fhnn.training.plans import DEFAULT_PLAN, PAPER_FHNN, PAPER_TRAIN, PLANS
from fhnn.training.run import RunConfig
from fhnn.training.trainer import (
    ADAM_CHUNK,
    AdamSettings,
    TrainConfig,
    Trainer,
    adam_chunk,
    adam_step,
    loss_terms,
    quasi_newton_objective,
    stack,
)

#: Anchors: earlier times to the targets on this 2-core CPU, and the authors' code on its own data.
BEFORE = {"solid_body_vortex": 296.0, "steady_vortex": 495.0}
AUTHORS_SECONDS = 1978.0


#: The paper's run (the ``adam`` plan): what these measurements were taken with.
PAPER_RUN = RunConfig().with_settings(PLANS["adam"].settings("fhnn"))


def fresh(ds, seed: int = 0):
    return MODELS["fhnn"].make(PAPER_RUN.model, MODELS["fhnn"].arguments(ds), seed)


def phases(ds) -> None:
    cfg = PAPER_TRAIN
    tr = Trainer(cfg, ds.train, ds.val)
    state = tr.init(fresh(ds))
    m, o, ac = state.model, state.opt_state, AdamSettings.of(cfg)
    step = {
        reg: seconds_per_call(
            lambda r=reg: adam_step(m, o, jnp.asarray(1), tr._train, tr.scales, tr._key, None, ac, r), 100
        )
        for reg in (True, False)
    }
    print("1. time per step (solid_body_vortex, float64, batch 256)")
    print(f"  Adam step with the flow penalty     {step[True] * 1e3:7.2f} ms")
    print(
        f"  Adam step without it (2nd half)     {step[False] * 1e3:7.2f} ms  "
        f"(ratio {step[False] / step[True]:.2f})"
    )
    plan = AdamSettings.of(PLANS[DEFAULT_PLAN].train)  # derivative loss alone, no penalty
    t_plan = seconds_per_call(
        lambda: adam_step(m, o, jnp.asarray(1), tr._train, tr.scales, tr._key, None, plan, False), 100
    )
    print(
        f"  Adam step of the default plan        {t_plan * 1e3:7.2f} ms  "
        f"(ratio {t_plan / step[True]:.2f}: derivative loss alone, no penalty)"
    )
    # what the trainer runs: ADAM_CHUNK steps per call, as the stored program it calls
    chunk = StoredProgram(adam_chunk)
    n = jnp.asarray(ADAM_CHUNK)
    t_chunk = (
        seconds_per_call(
            lambda: chunk(m, o, jnp.asarray(1), n, tr._train, tr.scales, tr._key, None, plan, False), 20
        )
        / ADAM_CHUNK
    )
    stored = StoredProgram(adam_step)
    t_stored = seconds_per_call(
        lambda: stored(m, o, jnp.asarray(1), tr._train, tr.scales, tr._key, None, plan, False), 100
    )
    print(
        f"    as the trainer runs it, {ADAM_CHUNK} steps per call {t_chunk * 1e3:7.2f} ms per step; "
        f"one step per call {t_stored * 1e3:.2f} ms (ratio {t_stored / t_chunk:.2f}: the call's "
        "dispatch, paid once per chunk)"
    )
    batch = {k: v[:256] for k, v in tr._train.items()} | {"key": jax.random.PRNGKey(0)}
    for which in (("deriv",), ("step",), ("deriv", "step"), ("flow",)):
        grad = eqx.filter_jit(
            eqx.filter_grad(lambda mm, w=which: sum(loss_terms(mm, batch, tr.scales)[k] for k in w))
        )
        t = seconds_per_call(lambda g=grad: g(m), 100)
        print(
            f"    gradient of {'+'.join(which):11s} alone {t * 1e3:7.2f} ms  ({t / step[True]:.0%} of a step)"
        )
    n = min(8000, len(tr.train_pairs))
    idx = np.sort(np.random.default_rng(2).choice(len(tr.train_pairs), n, replace=False))
    big = {**tr.train_pairs.subset(idx).as_jax(), "key": jax.random.PRNGKey(4)}
    part, _ = m.warmup()
    for label, model in (("warm-up part", part), ("whole model", m)):
        params, static = eqx.partition(model, eqx.is_array)

        @jax.jit
        def value_and_grad(p, data, static=static):
            return jax.value_and_grad(lambda q: quasi_newton_objective(q, static, data, tr.scales, cfg))(p)

        t = seconds_per_call(lambda f=value_and_grad, p=params: f(p, big), 10)
        print(f"  quasi-Newton value+gradient, {label:12s} ({n} pairs) {t:.3f} s")


def compile_times(ds, path: Path) -> None:
    print("2. compilation of the Adam program the trainer runs (first two calls minus two calls)")
    cfg = PAPER_TRAIN.replace(steps=1000)
    with tempfile.TemporaryDirectory() as cache:
        script = (
            "import sys, time; sys.path.insert(0, 'benchmarks');"
            "import jax, jax.numpy as jnp; from fhnn.runtime import use_compilation_cache;"
            f"use_compilation_cache({cache!r});"
            "from fhnn.data.dataset import read_dataset; from training_speed import first_call;"
            f"print(first_call(read_dataset({str(path)!r}), {cfg.steps}, stored=sys.argv[1] == 'stored'))"
        )
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(["benchmarks", os.environ.get("PYTHONPATH", "")])}
        runs = [
            float(
                subprocess.run(
                    [sys.executable, "-c", script, how], capture_output=True, text=True, env=env, check=True
                ).stdout.split()[-1]
            )
            for how in ("stored", "stored", "plain", "plain")
        ]
    use_compilation_cache(None)
    first_call(ds, cfg.steps, seed=0)  # this process's first job of these shapes
    same = first_call(ds, cfg.steps, seed=5)
    print(f"  first job, empty cache                     {runs[0]:6.2f} s")
    print(f"  second job, same process (seed 5)          {same:6.2f} s")
    print(f"  second job, new process, stored executable {runs[1]:6.2f} s  (target < 1 s)")
    print(f"  second job, new process, traced, JAX cache {runs[3]:6.2f} s  (ratio {runs[3] / runs[1]:.1f})")
    rollout_compile_times(path)


#: What a new process does before timing a program's first call: the compilation cache folder
#: ``sys.argv[1]``, the data set ``sys.argv[2]`` and a default FHNN on it, ``m``.
_SCRIPT_HEAD = (
    "import sys, time; sys.path.insert(0, 'benchmarks'); from fhnn.runtime import use_compilation_cache;"
    "use_compilation_cache(sys.argv[1]); from _common import seconds_per_call; import numpy as np;"
    "from fhnn.data.dataset import read_dataset; from fhnn.models.registry import MODELS;"
    "from fhnn.training.run import RunConfig; from fhnn.evaluation.predict import estimate_states;"
    "from fhnn.training.plans import PLANS;"
    "ds = read_dataset(sys.argv[2]); kind = MODELS['fhnn'];"
    "m = kind.make(RunConfig().with_settings(PLANS['adam'].settings('fhnn')).model, kind.arguments(ds), 0);"
    "sp = ds.test;"
)

#: A new process's first rollout of a model over 5 s of the test split (what ``fhnn evaluate``
#: runs), in seconds less the same rollout compiled; ``$EQX_ON_ERROR`` and ``$FHNN_EXECUTABLES`` as
#: the caller sets them.
_ROLLOUT = _SCRIPT_HEAD + (
    "t = sp.t[..., :101];"
    "t0 = time.perf_counter(); m.predict(sp.states, sp, t, 1e-10, 1e-10); first = time.perf_counter() - t0;"
    "print(first - seconds_per_call(lambda: m.predict(sp.states, sp, t, 1e-10, 1e-10), 2))"
)

#: The same for the fit of ``fhnn predict --history`` (:func:`fhnn.evaluation.predict.estimate_states`)
#: on the first ``sys.argv[3]`` samples of 4 test trajectories (positions with 1 mm noise).
_FIT = _SCRIPT_HEAD + (
    "k = int(sys.argv[3]); t = np.tile(sp.t[:k], (4, 1)); rng = np.random.default_rng(0);"
    "pos = sp.states[:4, :k, :2] + 1e-3 * rng.normal(size=(4, k, 2));"
    "t0 = time.perf_counter(); estimate_states(m, t, pos); first = time.perf_counter() - t0;"
    "print(first - seconds_per_call(lambda: estimate_states(m, t, pos), 2))"
)


def _first_calls(
    script: str, path: Path, env: dict[str, str], extra: tuple[str, str] = ("", "")
) -> list[float]:
    """What ``script`` prints (a first call's seconds) in two new processes sharing an empty
    compilation cache folder, the second after the first; ``extra``: each one's third argument."""
    with tempfile.TemporaryDirectory() as cache:
        return [
            float(
                subprocess.run(
                    [sys.executable, "-c", script, cache, str(path), arg],
                    capture_output=True,
                    text=True,
                    env={**os.environ, **env},
                    check=True,
                ).stdout.split()[-1]
            )
            for arg in extra
        ]


def rollout_compile_times(path: Path) -> None:
    """A rollout's compilation (5 s of the test split, the FHNN defaults) in a first and a second
    process sharing a compilation cache folder: as fhnn runs it (``EQX_ON_ERROR=nan``,
    :data:`fhnn.runtime.EQX_ON_ERROR_DEFAULT`, and the rollout a
    :class:`~fhnn.executables.StoredProgram`, which a later process runs untraced), with the store
    off (``FHNN_EXECUTABLES=off``: traced in every process, its compilation from JAX's cache), and
    with Equinox's default for its runtime checks as well (``EQX_ON_ERROR=raise``: Diffrax's checks
    call back into Python, and JAX neither caches nor exports a program that does)."""
    print("   a rollout (5 s of the test split, FHNN defaults): its first call less a compiled call")
    rows = {}
    for label, mode, store in (
        ("fhnn (stored)", "nan", "on"),
        ("store off", "nan", "off"),
        ("store off, raise", "raise", "off"),
    ):
        rows[label] = first, second = _first_calls(_ROLLOUT, path, {"EQX_ON_ERROR": mode, STORE_ENV: store})
        print(
            f"  {label:17s} (EQX_ON_ERROR={mode:5s})  first process {first:6.2f} s, "
            f"second process {second:6.2f} s"
        )
    stored = rows["fhnn (stored)"][1]
    print(
        f"  second process, stored against traced: {stored:.2f} s against {rows['store off'][1]:.2f} s "
        f"(ratio {rows['store off'][1] / stored:.1f}); against Equinox's default: "
        f"{rows['store off, raise'][1]:.2f} s (ratio {rows['store off, raise'][1] / stored:.1f})"
    )
    # 19 samples, then 23 in a new process: another history length in the same rung (24) of the
    # fit's padding ladder
    print("   fhnn predict's fit of a history, first call less a compiled one (4 tracks, 19 then 23 samples)")
    for label, store in (("stored", "on"), ("store off", "off")):
        first, second = _first_calls(_FIT, path, {STORE_ENV: store}, ("19", "23"))
        print(f"  {label:10s} first process {first:6.2f} s, second process (another length) {second:6.2f} s")


def first_call(ds, steps: int, seed: int = 0, stored: bool = True) -> float:
    """Seconds of the first two calls of a new trainer's Adam program (one step each; the second
    is fed the first's model and optimiser state, as in training, so a program compiled again for
    them is counted), less two compiled calls: the program as the trainer runs it (``stored``: a
    :class:`~fhnn.executables.StoredProgram` of :func:`adam_chunk`, whose exported module a
    process stored before is read untraced from the compilation cache folder), or the plain jitted
    program."""
    cfg = PAPER_TRAIN.replace(steps=steps, seed=seed)
    tr = Trainer(cfg, ds.train, ds.val)
    state = tr.init(fresh(ds, seed))
    one = jnp.asarray(1)
    rest = (tr._train, tr.scales, tr._key, None, AdamSettings.of(cfg), True)
    step = StoredProgram(adam_chunk) if stored else adam_chunk
    t0 = time.perf_counter()
    model, opt_state, _ = step(state.model, state.opt_state, jnp.asarray(0), one, *rest)
    model, opt_state, _ = jax.block_until_ready(step(model, opt_state, jnp.asarray(1), one, *rest))
    first = time.perf_counter() - t0
    return first - 2 * seconds_per_call(lambda: step(model, opt_state, jnp.asarray(2), one, *rest), 10)


def seeds_as_one(ds, n: int) -> None:
    """``n`` seeds' Adam steps as one ``vmap``-ed program against ``n`` sequential steps, for the
    step with every loss term and the penalty (width 64, the training defaults) and for the step
    ``fhnn train`` runs (the default plan: derivative loss alone, no penalty, its width)."""
    print(f"3. {n} seeds as one program (vmap over stacked models) against {n} sequential steps")
    plan = PLANS[DEFAULT_PLAN]
    _seeds_as_one(ds, n, "all terms and the penalty, width 64", PAPER_TRAIN, PAPER_FHNN, True)
    _seeds_as_one(ds, n, "the default plan's step", plan.train, plan.model.get("fhnn", {}), False)


def _seeds_as_one(ds, n: int, label: str, cfg: TrainConfig, model_settings: dict, regularize: bool) -> None:
    """One row of :func:`seeds_as_one`; then the same model at ``n`` times the batch, which bounds
    what stacking can gain on this CPU."""
    model_cfg = RunConfig().with_settings({f"model.{k}": v for k, v in model_settings.items()}).model
    args = MODELS["fhnn"].arguments(ds)
    ac = AdamSettings.of(cfg)
    trainers = [Trainer(cfg, ds.train, ds.val) for _ in range(n)]
    states = [t.init(MODELS["fhnn"].make(model_cfg, args, s)) for s, t in enumerate(trainers)]
    data, scales = trainers[0]._train, trainers[0].scales
    keys = jnp.stack([jax.random.PRNGKey(s + 1) for s in range(n)])
    models = stack([s.model for s in states])
    opts = stack([s.opt_state for s in states])

    size = jnp.asarray(ADAM_CHUNK)

    def chunk(model, opt_state, key, config):
        return adam_chunk(model, opt_state, jnp.asarray(1), size, data, scales, key, None, config, regularize)

    # the programs the trainer runs: ADAM_CHUNK steps per call, for one member and (fhnn train
    # --seeds N, trainer.run_together) for the members stacked
    stacked = (models, opts, jnp.asarray(1), size, data, scales, keys, None, ac, regularize, True)
    one = seconds_per_call(lambda: adam_chunk(*stacked), 10) / ADAM_CHUNK
    seq = (
        seconds_per_call(
            lambda: [chunk(s.model, s.opt_state, k, ac) for s, k in zip(states, keys, strict=True)], 10
        )
        / ADAM_CHUNK
    )
    print(
        f"  {label}: {n} sequential steps {seq * 1e3:7.2f} ms; one vmapped step {one * 1e3:7.2f} ms; "
        f"throughput ratio {seq / one:.2f} (target ≥ 2)"
    )
    # why: a step's time grows with the pairs it sees, so stacking seeds stacks work
    m, o = states[0].model, states[0].opt_state
    wide = AdamSettings.of(cfg.replace(batch_size=n * cfg.batch_size))
    single = seconds_per_call(lambda: chunk(m, o, keys[0], ac), 10) / ADAM_CHUNK
    bigger = seconds_per_call(lambda: chunk(m, o, keys[0], wide), 10) / ADAM_CHUNK
    print(
        f"    one model, batch {cfg.batch_size} -> {n * cfg.batch_size}: {single * 1e3:.2f} -> "
        f"{bigger * 1e3:.2f} ms per step (×{bigger / single:.2f} for ×{n} the pairs; in the sequential "
        f"loop a step took {seq / n * 1e3:.2f} ms, {seq / n / single:.2f}× a lone step)"
    )


def ensemble_end_to_end(out: Path, n: int, changes: dict) -> None:
    """``fhnn train --seeds n`` on ``steady_vortex`` (default data set, the default plan as
    ``fhnn train`` builds it, with ``changes`` on top), the members' Adam phases as one program
    (what the command runs) against the members one after another, and where the two runs' Adam
    records part (the vmapped sums differ in the last bits, which Adam's path amplifies)."""
    from fhnn.training.ensemble import train_members
    from fhnn.training.plans import data_settings, default_settings
    from fhnn.training.run import Run

    ds, _ = dataset("steady_vortex", out)
    settings = {**default_settings(ds), **data_settings(ds), **{f"train.{k}": v for k, v in changes.items()}}
    shown = ", ".join(f"{k}={v}" for k, v in changes.items()) or "none"
    print(f"5. fhnn train --seeds {n} on steady_vortex, default plan (changed: {shown}), end to end")
    times, runs = {}, {}
    # together first: the polish and the single-member Adam program the second pass compiles (or
    # reuses) favour the members one after another, so the ratio errs low
    for together in (True, False):
        folder = Path(tempfile.mkdtemp(dir=out))
        members = [
            Run.create(folder / f"seed-{s}", ds, RunConfig().with_settings({**settings, "train.seed": s}))
            for s in range(n)
        ]
        members[0].train(ds, until=0, save=False)  # compile the warm-up outside the timing
        members[0].state = None
        t0 = time.perf_counter()
        train_members(members, ds, together=together)
        times[together], runs[together] = time.perf_counter() - t0, members
    apart = []  # per member: the first Adam record whose validation loss differs by more than 1e-9
    for a, b in zip(runs[True], runs[False], strict=True):
        adam = [
            (ra, rb) for ra, rb in zip(a.state.history, b.state.history, strict=False) if "phase" not in ra
        ]
        apart.append(
            next((ra["step"] for ra, rb in adam if abs(ra["val_total"] / rb["val_total"] - 1) > 1e-9), None)
        )
    first = next(r["step"] for r in runs[True][0].state.history if "phase" not in r)
    early = max(
        abs(ra["val_total"] / rb["val_total"] - 1)
        for a, b in zip(runs[True], runs[False], strict=True)
        for ra, rb in zip(a.state.history, b.state.history, strict=False)
        if ra["step"] == first and "phase" not in ra
    )
    best = max(
        abs(a.state.best_val / b.state.best_val - 1) for a, b in zip(runs[True], runs[False], strict=True)
    )
    print(
        f"  one after another {times[False]:.1f} s; Adam phases together {times[True]:.1f} s "
        f"(compilation included); ratio {times[False] / times[True]:.2f}"
    )
    print(
        f"  the members' validation losses agree to {early:.1e} relative at the first Adam record (step "
        f"{first}) and to 1e-9 up to steps {', '.join(str(s) for s in apart)} (None: throughout); "
        "the order of the vmapped sums changes the last bits, and Adam's path at this rate amplifies "
        f"them, as a different machine would; the best validation loss after the polish differs by {best:.1e}"
    )


def to_targets(out: Path) -> None:
    print(
        "4. time to the accuracy targets (benchmarks/fhnn_targets.py, the default plan as fhnn train runs it)"
    )
    for name, only in (("solid_body_vortex", "solid"), ("steady_vortex", "steady")):
        done = subprocess.run(
            [sys.executable, "benchmarks/fhnn_targets.py", "--only", only, "--out", str(out / only)],
            capture_output=True,
            text=True,
        )
        if done.returncode != 0:  # say why, and go on with the next data set
            tail = done.stderr.strip().splitlines()[-5:]
            print(f"  {name}: fhnn_targets.py failed (exit {done.returncode}):", *tail, sep="\n    ")
            continue
        log = done.stdout
        lines = [
            l
            for l in log.splitlines()
            if "trained in" in l or "RMSE" in l or "max rel" in l or "relative L2" in l
        ]
        secs = float(next(l for l in lines if "trained in" in l).split("trained in")[1].split()[0])
        print(
            f"  {name}: {secs:.0f} s, {BEFORE[name] / secs:.2f}× faster than before ({BEFORE[name]:.0f} s), "
            f"{AUTHORS_SECONDS / secs:.1f}× faster than the authors' code ({AUTHORS_SECONDS:.0f} s)"
        )
        for line in lines[1:]:
            print("   ", line.strip())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--targets", action="store_true", help="also train to the accuracy targets (~5 min)")
    p.add_argument("--out", type=Path, default=Path("benchmarks/_training_speed"))
    p.add_argument(
        "--ensemble",
        action="store_true",
        help="also time fhnn train --seeds N end to end, Adam phases together and apart (~10 min)",
    )
    p.add_argument(
        "--ensemble-train",
        type=json.loads,
        default={},
        help="JSON of train.* changes for --ensemble (e.g. '{\"steps\": 2000}' for a quick check)",
    )
    p.add_argument(
        "--ensemble-only",
        action="store_true",
        help="only section 5 (--ensemble), for a machine whose sections 1-4 are measured already",
    )
    p.add_argument(
        "--rollout-only", action="store_true", help="only the rollout's compilation (end of section 2)"
    )
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    print(
        f"fhnn {fhnn.__version__}, jax {jax.__version__}, {jax.devices()[0].platform}, {os.cpu_count()} CPUs"
    )
    if args.rollout_only:
        rollout_compile_times(dataset("solid_body_vortex", args.out)[1])
        return
    if not args.ensemble_only:
        ds, path = dataset("solid_body_vortex", args.out)
        phases(ds)
        compile_times(ds, path)
        seeds_as_one(ds, args.seeds)
        if args.targets:
            to_targets(args.out)
    if args.ensemble or args.ensemble_only:
        ensemble_end_to_end(args.out, args.seeds, args.ensemble_train)


if __name__ == "__main__":
    if sys.argv[1:] in ([], ["--targets"]):  # the default question: its printed answer is the result file
        with printed_result("training_speed" + ("_targets" if sys.argv[1:] else "")):
            main()
    else:
        main()
