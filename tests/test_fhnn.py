"""FHNN model, training, checkpoints, rollout and metrics."""

import dataclasses
import itertools
import json
import re

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fhnn.errors import ConfigError, DataFormatError
from fhnn.evaluation.metrics import trajectory_metrics
from fhnn.evaluation.rollout import rollout
from fhnn.models.fhnn import FHNN, cap, uncap
from fhnn.models.fhnn import fhnn_arguments as build_arguments
from fhnn.models.registry import MODELS
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.flows import AbstractFlow
from fhnn.training.run import Run, RunConfig, check_trainable

from .conftest import PAPER_RUN, arrays, paper_fhnn, paper_train, small_dataset


class StreamOnly(AbstractFlow):
    """A flow known only through its stream function: velocity by autodiff, as in the stream net."""

    inner: AbstractFlow

    @property
    def time_dependent(self):
        return self.inner.time_dependent

    def stream(self, xy, t):
        return self.inner.stream(xy, t)


@pytest.mark.parametrize(
    "name", ["steady_vortex", "time_varying_vortex", "obstacle", "wave", "solid_body_vortex"]
)
def test_fhnn_with_true_stream_function_and_laws_reproduces_derivs(name):
    ds = small_dataset(name)
    body = ds.body()
    truth = EquationsOfMotion.of(StreamOnly(inner=ds.scenario_object().flow()), body)
    model = FHNN(eom=truth)
    split = ds.train
    f = jax.vmap(jax.vmap(model, in_axes=(0, 0, 0)), in_axes=(0, None, 0))
    pred = np.asarray(f(jnp.asarray(split.states_clean), jnp.asarray(split.t), jnp.asarray(split.forces)))
    scale = np.abs(split.derivs).max()
    assert np.abs(pred - split.derivs).max() <= 1e-12 * max(scale, 1.0)


def test_cap_maps():
    caps = jnp.asarray([60.0, 60.0, 2.0, 10.0])
    z = jnp.linspace(-30, 30, 301)[:, None] * jnp.ones(4)
    tanh_map = np.asarray(jax.vmap(lambda v: cap(v, caps, "tanh"))(z))
    sig_map = np.asarray(jax.vmap(lambda v: cap(v, caps, "sigmoid"))(z))
    assert (tanh_map > 0).all() and (tanh_map < np.asarray(caps)).all()
    assert tanh_map[0].max() < 1e-12  # reaches (almost) zero: m_a < 30 and c_l < 5 are expressible
    # the paper's printed map cannot go below C/2 (docs/spec.md §4.1 erratum)
    assert (sig_map >= np.asarray(caps) / 2).all()
    # ≈ softplus while small
    small = jnp.asarray([-3.0, -3.0, -3.0, -3.0])
    np.testing.assert_allclose(
        np.asarray(cap(small, caps, "tanh")), np.asarray(jax.nn.softplus(small)), rtol=1e-3
    )
    for kind, values in (
        ("tanh", np.array([12.0, 20.0, 0.8, 3.0])),
        ("sigmoid", np.array([40.0, 50.0, 1.5, 7.0])),
    ):
        back = np.asarray(cap(jnp.asarray(uncap(values, np.asarray(caps), kind)), caps, kind))
        np.testing.assert_allclose(back, values, rtol=1e-12)
    with pytest.raises(ConfigError, match="must lie inside the range of the sigmoid cap map"):
        paper_fhnn(cap_map="sigmoid")  # default init (10, 10, 0.5, 2) is below C/2


def test_metrics_on_hand_made_arrays():
    t = np.arange(0, 5.01, 0.5)
    truth = np.zeros((2, t.size, 4))
    pred = np.zeros_like(truth)
    pred[0, :, 0] = 0.003 * t  # trajectory 0: x error grows linearly (3 mm/s)
    pred[1, :, 1] = 0.004  # trajectory 1: constant 4 mm error in y
    pred[1, :, 3] = 0.1  # and 0.1 m/s error in vy
    m = trajectory_metrics(pred, truth, t, 2)  # checkpoints t = 1, 2
    expected_mse = (0.003**2 + 0.006**2 + 2 * 0.004**2) / 8
    assert m["mse_pos"] == pytest.approx(expected_mse)
    assert m["rmse_pos"] == pytest.approx(np.sqrt(expected_mse))
    assert m["rmse_vel"] == pytest.approx(np.sqrt(2 * 0.1**2 / 8))
    assert m["ade"] == pytest.approx((0.003 + 0.006 + 0.004 + 0.004) / 4)
    assert m["fde"] == pytest.approx((0.006 + 0.004) / 2)
    assert m["within_eps"] == 1.0 and m["diverged"] == 0
    paper = trajectory_metrics(pred, truth, t, 2, include_zero=True)  # t = 0 adds zero error for traj 0
    assert paper["ade"] == pytest.approx((0.003 + 0.006 + 0.004 * 3) / 6)
    pred[1, 6, 0] = np.nan  # trajectory 1 diverges at t = 3 s
    assert trajectory_metrics(pred, truth, t, 2)["diverged"] == 0
    late = trajectory_metrics(pred, truth, t, 4)
    assert late["diverged"] == 1 and late["within_eps"] == 0.0  # trajectory 0 ends 12 mm off
    # the diverged trajectory is not left out: its error is infinite, and so is every average
    assert all(late[k] == np.inf for k in ("mse_pos", "rmse_pos", "rmse_vel", "ade", "fde"))
    with pytest.raises(ConfigError, match="horizon 9 s exceeds"):
        trajectory_metrics(pred, truth, t, 9)


@pytest.fixture(scope="module")
def data():
    return small_dataset("steady_vortex", n_traj=30, duration=5.0)


def test_short_training_lowers_validation_error(data, tmp_path):
    run = Run.create(
        tmp_path / "r",
        data,
        RunConfig(model=paper_fhnn(width=32), train=paper_train(steps=600, val_every=100, lr=3e-3)),
    )
    state = run.train(data, save=False)
    first, best = state.history[0], state.best_val
    initial = run.skeleton()
    from fhnn.training.trainer import Trainer

    untrained = Trainer(run.train_config, data.train, data.val).validate(initial)
    assert best < (untrained["deriv"] + untrained["step"]) / 50, (untrained, first, best)


def test_checkpoint_round_trip_and_exact_resume(data, tmp_path):
    cfg = paper_fhnn(width=16)
    tc = paper_train(steps=40, val_every=10, batch_size=32, warmup_steps=4, lbfgs_pairs=200)
    straight = Run.create(tmp_path / "a", data, RunConfig(model=cfg, train=tc))
    straight.train(data)
    stopped = Run.create(tmp_path / "b", data, RunConfig(model=cfg, train=tc))
    stopped.train(data, until=20)
    resumed = Run.load(tmp_path / "b")
    assert resumed.state.step == 20
    resumed.train(data)
    loaded = Run.load(tmp_path / "a")
    s = jnp.asarray(data.test.states[0, 3])
    f = jnp.asarray([0.3, -0.2])
    for model in (resumed.state.model, loaded.state.model):
        np.testing.assert_array_equal(
            np.asarray(model(s, 0.15, f)), np.asarray(straight.state.model(s, 0.15, f))
        )
    assert loaded.state.history == straight.state.history


def test_bad_checkpoints_and_data(data, tmp_path):
    run = Run.create(
        tmp_path / "a", data, RunConfig(model=paper_fhnn(width=8), train=paper_train(steps=2, val_every=1))
    )
    run.train(data)
    with pytest.raises(DataFormatError, match="checkpoint is a 'fhnn' model, not 'hnn'"):
        Run.load(tmp_path / "a", expect_model="hnn")
    with pytest.raises(DataFormatError, match="not an fhnn run"):
        Run.load(tmp_path)
    (tmp_path / "a" / "model.eqx").write_bytes(b"garbage")
    with pytest.raises(DataFormatError, match="checkpoint files missing or incompatible"):
        Run.load(tmp_path / "a")
    data.train.states[0, 0, 0] = np.nan
    try:
        with pytest.raises(DataFormatError, match="split 'train': states contains NaN"):
            check_trainable(data)
    finally:
        data.train.states[0, 0, 0] = data.train.states_clean[0, 0, 0]


def test_rollout_tolerance_error_is_far_below_reported_errors(data):
    # a random (untrained) FHNN is a rough vector field; its rollout at the default tolerance must
    # agree with a 1000x tighter solve far below the accuracy targets (1e-5 m)
    model = MODELS["fhnn"].make(paper_fhnn(width=16), build_arguments(data), 3)
    loose = rollout(model, data.test)
    tight = rollout(model, data.test, rtol=1e-13, atol=1e-13)
    assert loose.ok.all() and tight.ok.all()
    assert np.abs(loose.states - tight.states).max() < 1e-9


def test_far_field_term_extrapolates_solid_body_rotation_and_is_not_penalised():
    from fhnn.physics.flows import SolidBodyRotation

    ds = small_dataset("solid_body_vortex")
    args = build_arguments(ds)
    model = MODELS["fhnn"].make(paper_fhnn(width=8), args, 0)
    flow = model.flow
    # zero the MLP, set Q so that ψ = −(Ω/2) r²: ψ_scale · ½ q ξ² with ξ = x / L
    zeroed = jax.tree_util.tree_map(lambda x: jnp.zeros_like(x) if eqx.is_array(x) else x, flow.mlp)
    q = -0.2 * flow.length_scale**2 / flow.psi_scale
    flow = eqx.tree_at(lambda f: (f.mlp, f.quadratic), flow, (zeroed, jnp.asarray([q, 0.0, q])))
    truth = SolidBodyRotation(omega=0.2)
    for xy in ([0.5, -1.0], [15.0, 12.0], [-20.0, 3.0]):  # inside and far outside the data
        np.testing.assert_allclose(
            np.asarray(flow.velocity(jnp.asarray(xy), 0.0)),
            np.asarray(truth.velocity(jnp.asarray(xy), 0.0)),
            rtol=1e-13,
        )
    model = eqx.tree_at(lambda m: m.eom.flow, model, flow)
    assert float(model.regularization(jnp.ones((4, 4)), jnp.zeros(4))["flow"]) == 0.0


class _Frozen(AbstractFlow):
    """A flow held at its state at ``t = 0``."""

    inner: AbstractFlow

    def stream(self, xy, t):
        return self.inner.stream(xy, jnp.zeros_like(t))


@pytest.mark.parametrize("name", ["time_varying_vortex", "wave"])
def test_flow_recovery_covers_the_data_time_window_of_a_time_dependent_flow(name):
    from fhnn.evaluation.recovery import flow_recovery

    data = small_dataset(name, n_traj=6, duration=4.0)
    truth = data.scenario_object().flow()
    assert truth.time_dependent
    exact = flow_recovery(truth, data)
    assert exact["rel_l2"] == 0.0 and len(exact["times"]) == 16
    assert exact["times"][0] == data.train.t[0] and exact["times"][-1] == pytest.approx(data.train.t[-1])
    frozen = _Frozen(truth)
    assert flow_recovery(frozen, data, t=0.0)["rel_l2"] < 1e-14  # at one instant a steady flow is exact
    assert flow_recovery(frozen, data)["rel_l2"] > 1e-3  # over the window it does not


class _SolidInside(AbstractFlow):
    """The obstacle's flow, but anything at all inside the cylinder (there is no fluid there)."""

    inner: AbstractFlow

    def stream(self, xy, t):
        inside = jnp.sum(xy**2) < 0.5**2
        return self.inner.stream(xy, t) + jnp.where(inside, 3.0 * xy[0] * xy[1], 0.0)


def test_flow_recovery_scores_the_fluid_only():
    """Trajectories pass within ``reach`` of the obstacle's cylinder, so the grid near them
    reaches into it; the flow's formula there is a continuation no body meets and nothing informs
    (it held ~90 % of a learned flow's squared error), and recovery leaves it out."""
    from fhnn.evaluation.recovery import flow_box, flow_grid, flow_recovery

    data = small_dataset("obstacle", n_traj=24, duration=20.0)
    truth = data.scenario_object().flow()
    x, y, near = flow_box(data)
    gx, gy = np.meshgrid(x, y)
    r = np.hypot(gx, gy)
    pos = data.train.states_clean[data.train.mask][:, :2]
    dist = np.min(
        np.hypot(gx.ravel()[:, None] - pos[None, :, 0], gy.ravel()[:, None] - pos[None, :, 1]), axis=1
    )
    reached = (dist <= 0.25).reshape(r.shape)
    assert (reached & (r < 0.5)).any(), "the grid within reach of a sample should cross the cylinder"
    np.testing.assert_array_equal(near, reached & (r >= 0.5))
    assert np.hypot(*flow_grid(data).T).min() >= 0.5
    assert flow_recovery(_SolidInside(truth), data)["rel_l2"] < 1e-12  # autodiff against closed form
    inside = jnp.asarray([0.3, 0.2])  # r = 0.36 m < R: the test flow does differ there
    assert not np.allclose(
        np.asarray(_SolidInside(truth).velocity(inside, 0.0)), np.asarray(truth.velocity(inside, 0.0))
    )


def test_recovery_of_the_truth_is_exact(data):
    from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery

    truth = data.equations()
    coef = coefficient_recovery(truth.coefficients, data)
    assert all(coef[k]["max_rel"] == 0.0 for k in ("m_ax", "m_ay", "c_q", "c_l"))
    assert coef["_coverage"]["sigma_max"] > coef["_coverage"]["sigma_min"] > 0
    flow = flow_recovery(truth.flow, data)
    assert flow["rel_l2"] == 0.0 and flow["points"] > 100
    bands = coef["_by_sigma"]
    assert sum(b["points"] for b in bands) == min(data.train.states_clean[..., 0].size, 20000)
    assert all(b[k] == 0.0 for b in bands for k in ("m_ax", "m_ay", "c_q", "c_l"))
    assert all(a["sigma_hi"] == b["sigma_lo"] for a, b in itertools.pairwise(bands))
    shares = [b["quadratic_share"] for b in bands]
    assert all(0 < x < 1 for x in shares) and shares == sorted(shares)


def test_recovery_shows_a_drag_equivalent_split_per_sigma_band(data):
    """c_l − δ with c_q + δ/(½ρAσ) gives the same drag; recovery must show the error where it is."""
    from fhnn.evaluation.recovery import coefficient_recovery, visited_r_sigma
    from fhnn.physics.body import AbstractCoefficients

    truth = data.equations()
    body = data.body()
    half_rho_a, delta = 0.5 * body.rho * body.area, 0.3

    class Shifted(AbstractCoefficients):
        inner: AbstractCoefficients

        def __call__(self, r, sigma):
            c = self.inner(r, sigma)
            return c.at[2].add(delta / (half_rho_a * sigma)).at[3].add(-delta)

    coef = coefficient_recovery(Shifted(truth.coefficients), data)
    points = visited_r_sigma(truth, data)
    want = np.asarray(jax.vmap(truth.coefficients)(jnp.asarray(points[:, 0]), jnp.asarray(points[:, 1])))
    rel_cq = delta / (half_rho_a * points[:, 1]) / want[:, 2]
    assert coef["c_l"]["max_rel"] == pytest.approx(delta / 3.0, rel=1e-12)
    assert coef["c_q"]["max_rel"] == pytest.approx(rel_cq.max(), rel=1e-9)
    for band in coef["_by_sigma"]:
        inside = (points[:, 1] >= band["sigma_lo"]) & (points[:, 1] <= band["sigma_hi"])
        assert band["c_q"] <= rel_cq[inside].max() * (1 + 1e-9)
        assert band["c_q"] >= rel_cq[points[:, 1] >= band["sigma_lo"]].min()
        assert band["m_ax"] == 0.0 and band["c_l"] == pytest.approx(delta / 3.0, rel=1e-12)
    # the error falls with σ: the first band holds the worst point
    assert coef["_by_sigma"][0]["c_q"] == pytest.approx(rel_cq.max(), rel=1e-9)
    # the total drag ½ρA c_q σ + c_l is unchanged by the split: what the data determine is exact
    assert coef["_drag"]["max_rel"] < 1e-13 and all(b["drag"] < 1e-13 for b in coef["_by_sigma"])

    # a wrong total drag shows there: c_l − δ alone is δ/(½ρA c_q σ + c_l) off at each point
    class Lowered(AbstractCoefficients):
        inner: AbstractCoefficients

        def __call__(self, r, sigma):
            return self.inner(r, sigma).at[3].add(-delta)

    wrong = coefficient_recovery(Lowered(truth.coefficients), data)
    drag = 3.0 + half_rho_a * want[:, 2] * points[:, 1]
    assert wrong["_drag"]["mean_rel"] == pytest.approx(np.mean(delta / drag), rel=1e-9)
    assert wrong["_by_sigma"][0]["drag"] == pytest.approx(np.max(delta / drag), rel=1e-9)


def test_cli_train_evaluate_inspect(data, tmp_path, capsys):
    import json

    from fhnn.cli.app import main
    from fhnn.data.dataset import write_dataset

    path = write_dataset(data, tmp_path / "d.h5")

    def run(argv):
        with pytest.raises(SystemExit) as info:
            main(argv)
        return info.value.code, capsys.readouterr()

    code, _ = run(
        [
            "train",
            str(path),
            "-o",
            str(tmp_path / "run"),
            "--plan",
            "adam",
            "--steps",
            "20",
            "--set",
            "model.width=8",
            "--set",
            "train.val_every=10",
            "-q",
        ]
    )
    assert code == 0
    code, out = run(["evaluate", str(tmp_path / "run"), "--horizons", "1,2", "--json"])
    assert code == 0
    result = json.loads(out.out)
    assert set(result) == {"1", "2", "diverged_count"}
    assert {"rmse_pos", "rmse_vel", "ade", "fde", "within_eps", "mse_pos", "outside_training"} <= set(
        result["1"]
    )
    code, out = run(["inspect", str(tmp_path / "run")])
    assert code == 0 and "flow: relative L2 error" in out.out
    assert "c_q by σ band" in out.out and "quadratic share" in out.out and "drag max rel." in out.out
    assert re.search(r"│ +drag(?: \[N·s/m\])? +│", out.out)
    code, out = run(["inspect", str(tmp_path / "run"), "--json"])
    drag = json.loads(out.out)["coefficients"]["_drag"]  # the total drag's ranges beside its errors
    assert 0 < drag["true_min"] <= drag["true_max"] and drag["learned_min"] <= drag["learned_max"]
    # the true drag grows with σ and does not depend on r: its least is at the slowest visited σ
    sigma = json.loads(out.out)["coefficients"]["_coverage"]["sigma_min"]
    _, _, c_q, c_l = np.asarray(data.equations().coefficients(jnp.asarray(1.0), jnp.asarray(sigma)))
    body = data.constants()
    assert drag["true_min"] == pytest.approx(0.5 * body["rho"] * body["A"] * c_q * sigma + c_l, rel=1e-12)
    for name in ("flow.png", "coefficients.png"):
        assert (tmp_path / "run" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, out = run(["evaluate", str(tmp_path / "run"), "--horizons", "1,99"])
    assert code == 2 and "horizon 99 s exceeds" in out.err
    code, out = run(["train", str(path), "-o", str(tmp_path / "r2"), "--ablation", "nope"])
    assert code == 2 and out.err.startswith("error: fhnn.ablation must be one of")


def test_warmup_fits_the_linear_flow_first_so_rotation_extrapolates(tmp_path):
    """On solid-body rotation the quasi-Newton warm-up (linear flow + coefficient net, stream MLP
    frozen at zero) recovers Ω, and the learned flow is then right far outside the data."""
    from fhnn.physics.flows import SolidBodyRotation

    ds = small_dataset("solid_body_vortex", n_traj=8, duration=2.0)
    config = paper_train(steps=0, warmup_steps=60, lbfgs_pairs=1500, val_every=20)
    run = Run.create(tmp_path / "r", ds, RunConfig(model=paper_fhnn(width=16), train=config))
    initial = run.skeleton()
    state = run.train(ds, save=False)
    model = state.best_model
    assert [r["iteration"] for r in state.history if r["phase"] == "warmup"] == [12, 24, 36, 48, 60]
    assert len(state.history) == 5 and state.step == 0
    # the stream MLP did not move during the warm-up; the linear flow and coefficients did
    leaves = jax.tree_util.tree_leaves
    for a, b in zip(leaves(initial.flow.mlp), leaves(model.flow.mlp), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert not np.array_equal(np.asarray(initial.flow.quadratic), np.asarray(model.flow.quadratic))
    truth = SolidBodyRotation(omega=0.2)
    for xy in ([1.0, -0.5], [20.0, 5.0], [-3.0, -25.0]):  # r ≤ 3.5 m in the data
        got = np.asarray(model.flow.velocity(jnp.asarray(xy), 0.0))
        want = np.asarray(truth.velocity(jnp.asarray(xy), 0.0))
        assert np.linalg.norm(got - want) < 1e-3 * np.linalg.norm(want), (xy, got, want)


def test_coefficients_held_outside_the_training_radii():
    ds = small_dataset("solid_body_vortex")
    args = build_arguments(ds)
    lo, hi = args["r_range"]
    radius = np.hypot(ds.train.states[..., 0], ds.train.states[..., 1])
    assert (lo, hi) == (radius.min(), radius.max())
    held = MODELS["fhnn"].make(paper_fhnn(width=8), args, 0).coefficients
    free = MODELS["fhnn"].make(paper_fhnn(width=8, r_extrapolation="net"), args, 0).coefficients
    at = lambda c, r: np.asarray(c(jnp.asarray(r), jnp.asarray(0.3)))  # noqa: E731
    np.testing.assert_array_equal(at(held, 5 * hi), at(held, hi))
    np.testing.assert_array_equal(at(held, 0.0), at(held, lo))
    np.testing.assert_array_equal(at(held, 0.5 * (lo + hi)), at(free, 0.5 * (lo + hi)))
    assert not np.allclose(at(free, 5 * hi), at(free, hi))
    # coefficients_in_r=False: functions of σ alone, the same net at r = 0 otherwise
    flat = MODELS["fhnn"].make(paper_fhnn(width=8, coefficients_in_r=False), args, 0).coefficients
    for r in (lo, 0.5 * (lo + hi), 5 * hi):
        np.testing.assert_array_equal(at(flat, r), at(free, 0.0))
    assert flat.r_range is None and held.r_range is not None  # no radius range it would not use
    assert not np.allclose(at(flat, 0.2), np.asarray(flat(jnp.asarray(0.2), jnp.asarray(0.05))))


def test_training_phase_settings_are_checked():
    with pytest.raises(ConfigError, match="warmup_steps"):
        paper_train(warmup_steps=-1)
    with pytest.raises(ConfigError, match="lbfgs_memory"):
        paper_train(lbfgs_memory=0)
    assert paper_train(steps=0).steps == 0


class _WaveCoefficients(eqx.Module):
    """Stands in for the stream MLP: the harmonic coefficients of the deep-water wave at ``ξ``
    (``ψ/psi_scale = c e^{ky} [cos(kx) cos(ωt) + sin(kx) sin(ωt)]``, ω = π·mode/time_scale)."""

    wave: eqx.Module
    length_scale: float
    psi_scale: float
    mode: int
    modes: int

    def __call__(self, xi):
        x, y = xi * self.length_scale
        k, w = self.wave.wavenumber, self.wave.omega
        c = self.wave.amplitude * w / k * jnp.exp(k * y) / self.psi_scale
        out = jnp.zeros(2 * self.modes + 1)
        return out.at[self.mode].set(c * jnp.cos(k * x)).at[self.modes + self.mode].set(c * jnp.sin(k * x))


def test_harmonic_time_basis_carries_a_travelling_wave_exactly():
    """ψ = MLP(ξ)·φ(t): with the wave's spatial coefficients in channel j (cos) and K + j (sin),
    where the 4 s period is 2·20/10 s of a 20 s window (j = 10), the stream net's velocity and
    material derivative (the Morison term) are the wave's, at times inside and past the window."""
    from fhnn.physics.flows import DeepWaterWave

    ds = small_dataset("wave", n_traj=6, duration=3.0)
    args = {**build_arguments(ds), "time_scale": 20.0}
    model = MODELS["fhnn"].make(paper_fhnn(width=8), args, 0)
    flow = model.flow
    assert flow.time_modes == 16 and flow.mlp.out_size == 33 and flow.mlp.in_size == 2
    wave = DeepWaterWave(amplitude=0.2, period=4.0)
    coeffs = _WaveCoefficients(wave, float(flow.length_scale), float(flow.psi_scale), 10, 16)
    flow = eqx.tree_at(lambda f: f.mlp, flow, coeffs)
    points = np.random.default_rng(0).uniform([-5, -3, 0], [5, -1, 45], (20, 3))
    for x, y, t in points:
        xy, tt = jnp.asarray([x, y]), jnp.asarray(t)
        np.testing.assert_allclose(flow.velocity(xy, tt), wave.velocity(xy, tt), rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(
            flow.material_derivative(xy, tt), wave.material_derivative(xy, tt), rtol=1e-10, atol=1e-13
        )


def test_harmonic_time_basis_resolves_periods_off_its_grid():
    """The basis's claim (``harmonic_basis``): tones whose periods are not 2T/j still lie in its span
    on the window, to 1e-9 with 16 modes down to a period of 3.3 s over 20 s — and not with 8."""
    from fhnn.models.fhnn import harmonic_basis

    tau = jnp.linspace(0.0, 1.0, 2001)
    for modes, limit in ((16, 1e-9), (8, None)):
        basis = np.asarray(jax.vmap(lambda s, m=modes: harmonic_basis(s, m))(tau))
        assert basis.shape == (2001, 2 * modes + 1)
        for period in (3.3, 4.4, 7.7, 50.0):
            tone = np.cos(2 * np.pi * 20.0 * np.asarray(tau) / period + 0.3)
            coef, *_ = np.linalg.lstsq(basis, tone, rcond=None)
            worst = np.abs(basis @ coef - tone).max()
            if limit is not None:
                assert worst < limit, (modes, period, worst)
            elif period == 3.3:
                assert worst > 0.1  # 8 modes reach down to periods of ~5 s only


def test_a_run_stored_before_the_harmonic_time_basis_loads_with_the_papers_form(tmp_path):
    """A run whose stored configuration lacks ``time_modes`` (written before the field existed)
    is rebuilt with ψ(x, y, t) = MLP(ξ, τ), the form its weights are, not the current default."""
    ds = small_dataset("time_varying_vortex", n_traj=6, duration=2.0)
    config = PAPER_RUN.with_settings({"model.width": 4, "model.time_modes": 0, "train.steps": 3})
    run = Run.create(tmp_path / "run", ds, config)
    run.train(ds)
    info_path = tmp_path / "run" / "run.json"
    info = json.loads(info_path.read_text())
    del info["model_config"]["time_modes"]
    info_path.write_text(json.dumps(info))
    loaded = Run.load(tmp_path / "run")
    assert loaded.model_config.time_modes == 0 and loaded.best_model.flow.mlp.in_size == 3
    for a, b in zip(arrays(loaded.best_model), arrays(run.state.best_model), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.parametrize("power", [2.0, 12.0])
def test_slow_weight_weighs_each_window_by_its_relative_speed(data, power):
    """``slow_weight = p``: each window's data terms weighted by ``min((σ̃/σ)^p, cap)`` over the
    batch's mean, σ the window's start relative speed under the model, σ̃ the batch median —
    checked against the unweighted terms of one window at a time."""
    from fhnn.data.windows import Windows
    from fhnn.models.fhnn import SLOW_WEIGHT_CAP, build_fhnn

    args = build_arguments(data)
    model = build_fhnn(paper_fhnn(width=8, slow_weight=power), key=jax.random.PRNGKey(3), **args)
    # a flow that is not zero, so that σ is not the body's own speed
    model = eqx.tree_at(lambda m: m.eom.flow.quadratic, model, jnp.asarray([0.3, 0.1, -0.2]))
    plain = dataclasses.replace(model, slow_weight=0.0)
    assert plain.slow_weight == 0.0 and model.slow_weight == power
    pairs = Windows.of(data.train, 2)
    spread = np.linspace(0, len(pairs) - 1, 40).astype(int)  # windows of many trajectories
    batch = {k: v[spread] for k, v in pairs.as_jax().items()}
    scales = (jnp.asarray([0.5, 0.4, 0.2, 0.3]), jnp.asarray([0.02, 0.03, 0.01, 0.01]))
    terms = eqx.filter_jit(lambda m, b: m.loss_terms(b, scales))
    one = [terms(plain, {k: v[i : i + 1] for k, v in batch.items()}) for i in range(40)]
    sigma = np.asarray(jax.vmap(model.eom.relative_speed)(batch["s"][:, 0], batch["t"][:, 0]))
    raw = (np.median(sigma) / sigma) ** power
    weight = np.minimum(raw, SLOW_WEIGHT_CAP)
    weight /= weight.mean()
    weighted, unweighted = terms(model, batch), terms(plain, batch)
    for name in ("deriv", "step"):
        per = np.asarray([float(t[name]) for t in one])
        assert float(weighted[name]) == pytest.approx(np.mean(weight * per), rel=1e-12)
        assert float(unweighted[name]) == pytest.approx(np.mean(per), rel=1e-12)
        assert float(weighted[name]) != pytest.approx(float(unweighted[name]), rel=1e-3)
    # the slowest windows weigh most; at p = 12 the cap binds
    assert weight[np.argmin(sigma)] == weight.max() and weight[np.argmax(sigma)] == weight.min()
    assert (raw.max() > SLOW_WEIGHT_CAP) == (power == 12.0)
    with pytest.raises(ConfigError, match="slow_weight"):
        paper_fhnn(slow_weight=-1.0)


def test_quasi_newton_phases_hold_the_slow_window_weights_fixed(data):
    """Under ``slow_weight`` the trainer's quasi-Newton phases weigh each window as the model they
    start from does, and hold those weights: the phase's objective then has the gradient it is
    given (central differences along it agree to 1e-6), where the weights
    recomputed at every point, their derivative left out, do not (a line search on them fails).
    The polish's first record is that objective at its start."""
    from fhnn.data.windows import Windows
    from fhnn.models.fhnn import build_fhnn, slow_window_weights
    from fhnn.training.trainer import Trainer, data_loss, quasi_newton_objective

    args = build_arguments(data)
    model = build_fhnn(paper_fhnn(width=8, slow_weight=2.0), key=jax.random.PRNGKey(3), **args)
    model = eqx.tree_at(lambda m: m.eom.flow.quadratic, model, jnp.asarray([0.3, 0.1, -0.2]))
    pairs = Windows.of(data.train, 2)
    batch = {k: v[np.linspace(0, len(pairs) - 1, 40).astype(int)] for k, v in pairs.as_jax().items()}
    sigma = jax.vmap(model.eom.relative_speed)(batch["s"][:, 0], batch["t"][:, 0])
    weight = model.quasi_newton_weights(batch)
    np.testing.assert_allclose(weight, slow_window_weights(sigma, 2.0), rtol=1e-13)
    assert dataclasses.replace(model, slow_weight=0.0).quasi_newton_weights(batch) is None

    config = paper_train(w_step=1.0)
    scales = (jnp.asarray([0.5, 0.4, 0.2, 0.3]), jnp.asarray([0.02, 0.03, 0.01, 0.01]))
    params, static = eqx.partition(model, eqx.is_array)
    flat, unravel = jax.flatten_util.ravel_pytree(params)

    def mismatch(b):  # along the gradient (the model's constants, of zero gradient, stay put)
        f = lambda x: quasi_newton_objective(unravel(x), static, b, scales, config)  # noqa: E731
        grad = jax.grad(f)(flat)
        direction, slope, h = grad / jnp.linalg.norm(grad), float(jnp.linalg.norm(grad)), 1e-5
        return (
            abs((float(f(flat + h * direction)) - float(f(flat - h * direction))) / (2 * h) - slope) / slope
        )

    assert mismatch({**batch, "weight": weight}) < 1e-6
    assert mismatch(batch) > 1e-3

    trainer = Trainer(paper_train(lbfgs_steps=1, lbfgs_pairs=64, val_every=1), data.train, data.val)
    state = trainer.polish(trainer.init(model))
    qn = trainer.batch(trainer.quasi_newton_windows(), jax.random.PRNGKey(trainer.config.seed + 4))
    held = data_loss(
        model.loss_terms({**qn, "weight": model.quasi_newton_weights(qn)}, trainer.scales), trainer.config
    )
    assert state.history[-1]["train_loss"] == pytest.approx(float(held), rel=1e-12)
    assert state.history[-1]["train_loss"] != pytest.approx(
        float(
            data_loss(
                dataclasses.replace(model, slow_weight=0.0).loss_terms(qn, trainer.scales), trainer.config
            )
        ),
        rel=1e-3,
    )
