"""FHNN: Floating-Body Hydrodynamic Neural Network (the paper's model).

The vector field is the analytic :class:`~fhnn.physics.dynamics.EquationsOfMotion` with two learned
parts in place of the unknown physics:

- :class:`StreamNet` ``ψ_θ(x, y)`` or ``ψ_θ(x, y, t)`` — an MLP whose gradient gives the flow
  ``u = ∇⊥ψ_θ`` (divergence-free by construction);
- :class:`CoefficientNet` ``g_φ(r, σ)`` — an MLP whose four raw outputs ``z`` become
  ``(m_ax, m_ay, c_q, c_l) = C · tanh(softplus(z) / C)``, ``C = (60, 60, 2, 10)``. The paper prints
  ``C · sigmoid(softplus(z)/C)``, which only reaches ``(C/2, C)`` (an erratum); it remains
  available as ``cap_map="sigmoid"``.

Beyond the paper, each a setting of :class:`FHNNConfig`: ``c_l`` one learned constant
(``linear_drag``) and the slow windows weighed up (``slow_weight``), so that the drag splits into
``c_l`` and ``c_q(σ)``; added masses held constant where the data leave them a free gauge
(``added_mass``); a learned linear far field beside the MLP (``far_field``); a harmonic basis in
time for a time-dependent flow (``time_modes``); the coefficients held at the edge of the training
radii (``r_extrapolation``); positions taken from the data's centre (``centre``). Why each, and
what it gains: the design note ``docs/design/model.md``.

Known body constants ``M, ρ, A, V`` come from the data set. Ablations (paper Table "ablation"):
``no_added_mass`` (m_a ≡ 0), ``no_linear_drag`` (c_l ≡ 0), ``no_flow`` (u ≡ 0), ``shallow`` (one
hidden layer), ``relu`` (ReLU activations).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.config import Config, check_nonnegative, check_positive, frozen_config
from fhnn.data.dataset import Dataset
from fhnn.errors import ConfigError
from fhnn.models.base import AbstractVectorField
from fhnn.physics.body import AbstractCoefficients
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.flows import AbstractFlow, StillWater

Array = jax.Array

#: The paper's ablations (its Table "ablation"): name → label.
ABLATIONS = {
    "no_added_mass": "no added mass",
    "no_linear_drag": "no linear drag",
    "no_flow": "no flow field",
    "shallow": "shallow net",
    "relu": "ReLU",
}
#: ``FHNNConfig.ablation``: "none" (the full model) or one of :data:`ABLATIONS`.
AblationName = Literal[("none", *ABLATIONS)]  # type: ignore[valid-type]
CAPS = (60.0, 60.0, 2.0, 10.0)
#: Largest weight of a slow window relative to one at the batch's median relative speed
#: (``FHNNConfig.slow_weight``).
SLOW_WEIGHT_CAP = 50.0


@frozen_config
class FHNNConfig(Config):
    """Architecture of an FHNN. The defaults are what ``fhnn train`` trains on noise-free data;
    the paper's are width 64 and slow_weight 0 (the ``adam`` plan). Each field is documented
    below it.
    """

    config_name = "fhnn"

    width: int = 32
    """Hidden units per layer of both nets (32: on the validation loss, width 32 reached 1.34e-9 in 90
    s against 7.8e-9 in 158 s at 64, ``solid_body_vortex``)."""
    depth: int = 3
    """Hidden layers of both nets (``shallow`` ablation: 1)."""
    activation: Literal["tanh", "relu"] = "tanh"
    """``"tanh"`` or ``"relu"`` (``relu`` ablation)."""
    cap_map: Literal["tanh", "sigmoid"] = "tanh"
    """``"tanh"`` (corrected, range (0, C)) or ``"sigmoid"`` (the paper's printed map)."""
    caps: tuple[float, float, float, float] = CAPS
    """C for (m_ax, m_ay, c_q, c_l)."""
    ablation: AblationName = "none"
    """One of none, no_added_mass, no_linear_drag, no_flow, shallow, relu."""
    time_dependent: bool | None = None
    """ψ(x, y, t) instead of ψ(x, y); None: from the data set's scenario."""
    fluid_inertia: bool | None = None
    """Morison inertia term from the learned ψ; None: from the data set's body."""
    init_coefficients: tuple[float, float, float, float] = (10.0, 10.0, 0.5, 2.0)
    """Coefficient values the net starts at (its last bias is set so)."""
    linear_drag: Literal["constant", "net"] = "constant"
    """``"constant"`` (one learned c_l: the σ → 0 limit of the drag) or "net" (c_l(r, σ) from g_φ, as in
    the paper; only ½ρA c_q σ + c_l is then identifiable)."""
    added_mass: Literal["net", "constant"] = "net"
    """``"net"`` (m_ax(r, σ), m_ay(r, σ) from g_φ, as in the paper) or "constant" (two learned constants):
    where the masses are not identifiable, only ``c / (M + m_a)`` (design note docs/design/model.md),
    ``fhnn train`` sets "constant"."""
    far_field: Literal["linear", "none"] = "linear"
    """``"linear"`` (MLP plus a learned linear flow, penalty on the MLP part) or "none"."""
    r_extrapolation: Literal["hold", "net"] = "hold"
    """``"hold"`` (the coefficient net sees r clipped to the training data's range) or "net" (the MLP's
    own extrapolation, as in the paper)."""
    coefficients_in_r: bool = True
    """Whether the coefficient net sees ``r`` (as in the paper); ``False``: the coefficients are
    functions of σ alone."""
    time_modes: int = 16
    """Harmonics K of a time-dependent flow's basis in time (see :class:`StreamNet`): ψ = MLP(ξ)·(1,
    cos(πjt/T), sin(πjt/T))_{j=1…K}, T the training data's time window; 16 resolve periods down to
    about T/6. 0: the paper's MLP(ξ, t/T). Unused for a steady flow."""
    slow_weight: float = 1.0
    """Exponent ``p`` of the weight ``min((σ̃/σ)^p, SLOW_WEIGHT_CAP)`` of each training window in the
    data loss, ``σ`` the relative speed at its start under the current model (in the quasi-Newton
    phases: under the model the phase starts from, held fixed), ``σ̃`` the batch's median (see
    :meth:`FHNN.loss_terms`); 0: every window alike. 1 (default) settles the drag split on noise-free
    observations; data with observation noise set 0 (:func:`~fhnn.training.plans.data_settings`); 2
    settles it on ``steady_vortex`` but not on every scenario (design note docs/design/model.md)."""
    centre: Literal["data", "origin"] = "data"
    """Where the flow net's inputs and the coefficients' ``r`` are taken from: "data" (the data
    set's :attr:`~fhnn.data.dataset.Dataset.centre`: the mean training position of imported data, the
    coordinate origin of a simulated scenario), which makes a model of imported data independent of
    where the table's origin lies; or "origin" (the table's coordinate origin)."""

    def validate(self) -> None:
        check_positive(self, "width", "depth")
        check_nonnegative(self, "time_modes", "slow_weight")
        if any(c <= 0 for c in self.caps):
            raise ConfigError(f"fhnn: caps must be > 0, got {self.caps}")
        for value, cap in zip(self.init_coefficients, self.caps, strict=True):
            lower = cap / 2 if self.cap_map == "sigmoid" else 0.0
            if not lower < value < cap:
                raise ConfigError(
                    f"fhnn: init_coefficients {self.init_coefficients} must lie inside the range of the "
                    f"{self.cap_map} cap map ({lower:g}, {cap:g}) for each coefficient"
                )

    @property
    def effective_depth(self) -> int:
        return 1 if self.ablation == "shallow" else self.depth

    @property
    def effective_activation(self) -> str:
        return "relu" if self.ablation == "relu" else self.activation


def _activation(name: str):
    return jax.nn.relu if name == "relu" else jnp.tanh


class StreamNet(AbstractFlow):
    """``ψ_θ = psi_scale · [MLP(ξ) + ½ ξᵀQξ + bᵀξ]`` [m²/s], ``ξ = x / length_scale``; for a
    time-dependent flow the MLP's ``2K + 1`` outputs are the coefficients of a harmonic basis in
    time, ``MLP(ξ)·φ(t)`` with ``φ = (1, cos(πjτ), sin(πjτ))``, ``j = 1 … K``,
    ``τ = t / time_scale``, ``K = time_modes`` (``time_modes = 0``: the paper's ``MLP(ξ, τ)``).

    ``quadratic = (Q_xx, Q_xy, Q_yy)`` and ``linear = b`` are the far-field linear flow (None: the
    paper's plain MLP). With ``origin = x₀`` [m], ``ξ = (x − x₀) / length_scale``.
    The scales are data-derived constants held as 0-d arrays behind
    ``stop_gradient`` (never trained): arrays, not static fields, so that models of the same
    architecture on different data sets share one compiled program.
    """

    mlp: eqx.nn.MLP | None  # None: sits out (the warm-up fits the linear flow alone)
    length_scale: Array  # [m]
    psi_scale: Array  # [m²/s]
    time_scale: Array  # [s]
    uses_time: bool = eqx.field(static=True)
    quadratic: Array | None = None
    linear: Array | None = None
    time_modes: int = eqx.field(static=True, default=0)
    origin: Array | None = None  # (2,) [m]

    @property
    def time_dependent(self) -> bool:
        return self.uses_time

    def _scaled(self, xy: Array) -> Array:
        xy = jnp.asarray(xy)
        if self.origin is not None:
            xy = xy - _const(self.origin)
        return xy / _const(self.length_scale)

    def net_stream(self, xy: Array, t: Array) -> Array:
        """The MLP part of ψ_θ [m²/s] (what the smoothness penalty acts on); 0 without the MLP."""
        if self.mlp is None:
            return jnp.zeros((), jnp.result_type(float))
        inp = self._scaled(xy)
        if not self.uses_time:
            return _const(self.psi_scale) * self.mlp(inp)[0]
        tau = jnp.asarray(t, inp.dtype) / _const(self.time_scale)
        if not self.time_modes:  # the paper's form: time as a third input
            return _const(self.psi_scale) * self.mlp(jnp.concatenate([inp, jnp.reshape(tau, (1,))]))[0]
        return _const(self.psi_scale) * jnp.dot(self.mlp(inp), harmonic_basis(tau, self.time_modes))

    def stream(self, xy: Array, t: Array) -> Array:
        psi = self.net_stream(xy, t)
        if self.quadratic is not None and self.linear is not None:
            xi = self._scaled(xy)
            q = self.quadratic
            far = 0.5 * (q[0] * xi[0] ** 2 + 2.0 * q[1] * xi[0] * xi[1] + q[2] * xi[1] ** 2)
            psi = psi + _const(self.psi_scale) * (far + jnp.dot(self.linear, xi))
        return psi


class CoefficientNet(AbstractCoefficients):
    """``g_φ(r, σ) → (m_ax, m_ay, c_q, c_l)`` through a capped positive map; ``r`` clipped to
    ``r_range`` [m] when given. The mask, input scales and ``r_range`` are constants, held
    as arrays behind ``stop_gradient`` (see :class:`StreamNet`)."""

    mlp: eqx.nn.MLP
    caps: tuple[float, ...] = eqx.field(static=True)
    cap_map: str = eqx.field(static=True)
    mask: Array  # (4,): 0 switches a coefficient off (the ablations)
    r_scale: Array  # [m]
    sigma_scale: Array  # [m/s]
    c_l_raw: Array | None = None
    mass_raw: Array | None = None  # (2,): constant added masses, raw
    r_range: Array | None = None  # (2,) [m]: min and max radius of the training positions
    uses_r: bool = eqx.field(static=True, default=True)  # False: functions of σ alone

    def __call__(self, r: Array, sigma: Array) -> Array:
        if not self.uses_r:
            r = jnp.zeros_like(r)
        elif self.r_range is not None:
            lo, hi = _const(self.r_range)
            r = jnp.clip(r, lo, hi)
        z = self.mlp(jnp.stack([r / _const(self.r_scale), sigma / _const(self.sigma_scale)]))
        if self.c_l_raw is not None:  # constant linear drag: one learned raw value
            z = z.at[3].set(self.c_l_raw)
        if self.mass_raw is not None:  # constant added masses: two learned raw values
            z = z.at[:2].set(self.mass_raw)
        return cap(z, jnp.asarray(self.caps), self.cap_map) * _const(self.mask)


def slow_window_weights(sigma: Array, power: float) -> Array:
    """Weights ``(B,)`` of windows whose start relative speeds are ``sigma`` ``(B,)`` [m/s]:
    ``min((σ̃/σ)^power, SLOW_WEIGHT_CAP)`` over their mean, ``σ̃`` the median of ``sigma``."""
    weight = jnp.minimum((jnp.median(sigma) / sigma) ** power, SLOW_WEIGHT_CAP)
    return weight / jnp.mean(weight)


@eqx.filter_jit
def _start_weights(eom: EquationsOfMotion, batch: dict[str, Array], power: float) -> Array:
    """:func:`slow_window_weights` ``(B,)`` of the windows of ``batch`` from the relative speeds
    at their starts under ``eom``."""
    return slow_window_weights(jax.vmap(eom.relative_speed)(batch["s"][:, 0], batch["t"][:, 0]), power)


def harmonic_basis(tau: Array, modes: int) -> Array:
    """``(1, cos(πjτ) for j = 1 … modes, sin(πjτ) for j = 1 … modes)`` at the scaled time ``τ``,
    shape ``(2·modes + 1,)``: on ``τ ∈ [0, 1]`` (the training window) it resolves every period
    down to about ``1.3 · 2/modes`` windows, off its grid too (a tone of period 3.3 s over a 20 s
    window to 1e-10 with 16 modes: half-periods and their sines together are overcomplete)."""
    phase = jnp.pi * tau * jnp.arange(1, modes + 1, dtype=jnp.result_type(tau))
    return jnp.concatenate([jnp.ones((1,), phase.dtype), jnp.cos(phase), jnp.sin(phase)])


def _array(value: Any) -> Array:
    """A float64 array, not weakly typed (an optimiser's update makes a weak scalar strong, and the
    compiled step would be traced again)."""
    return jnp.asarray(value, dtype=jnp.result_type(float))


def _const(value: Array) -> Array:
    """A data-derived constant of a model: an array leaf the optimisers never move (zero gradient)."""
    return jax.lax.stop_gradient(value)


def cap(z: Array, caps: Array, kind: str) -> Array:
    """``C·tanh(softplus(z)/C)`` (kind "tanh") or the paper's ``C·sigmoid(softplus(z)/C)``."""
    sp = jax.nn.softplus(z) / caps
    return caps * (_tanh_nonnegative(sp) if kind == "tanh" else jax.nn.sigmoid(sp))


def _tanh_nonnegative(x: Array) -> Array:
    """``tanh(x)`` for ``x ≥ 0`` as ``−expm1(−2x) / (1 + exp(−2x))``, increasing in floating point.

    XLA's float64 ``tanh`` on the CPU is not monotone near saturation: on a grid of step 1e-5 it
    decreases at 158,337 of 4 million points of [0, 40], from x ≈ 12.4 on, by an ulp or two, and
    so the cap map did too (a coefficient could fall as its raw output rose). This form has no
    decrease on that grid, within 6e-16 of ``numpy.tanh``; it reaches 1 exactly from x ≈ 19.
    """
    e = jnp.exp(-2.0 * x)
    return -jnp.expm1(-2.0 * x) / (1.0 + e)


def uncap(value: np.ndarray, caps: np.ndarray, kind: str) -> np.ndarray:
    """Inverse of :func:`cap`: the raw ``z`` that gives ``value``."""
    x = value / caps
    sp = np.arctanh(x) if kind == "tanh" else np.log(x / (1 - x))
    sp = sp * caps
    return sp + np.log(-np.expm1(-sp))  # inverse softplus


class FHNN(AbstractVectorField):
    """The FHNN vector field: learned ψ and coefficients inside the analytic equations of motion."""

    eom: EquationsOfMotion
    slow_weight: float = eqx.field(static=True, default=0.0)

    @property
    def flow(self) -> AbstractFlow:
        return self.eom.flow

    @property
    def coefficients(self) -> AbstractCoefficients:
        return self.eom.coefficients

    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        return self.eom(state, t, force)

    def loss_terms(self, batch: dict[str, Array], scales: tuple[Array, Array]) -> dict[str, Array]:
        """The vector field's loss terms; with ``slow_weight = p > 0`` each window weighted by
        ``min((σ̃/σ)^p, SLOW_WEIGHT_CAP)`` (normalised to mean 1 over the batch), ``σ`` its start's
        relative speed under this model and ``σ̃`` the batch's median, held constant in the
        gradient. Why: the drag force is ``K(σ)·v_rel``, so an error in ``K`` costs a window in
        proportion to σ²; the split of ``K(σ) = ½ρA c_q(σ) σ + c_l`` into its parts rests on the
        slowest windows (``c_l = K(0)``), which an unweighted mean hardly sees. Weights the batch
        holds already (``"weight"``, e.g. :meth:`quasi_newton_weights` held by the trainer) are
        used instead."""
        if self.slow_weight > 0 and "weight" not in batch:
            weight = _start_weights(self.eom, batch, self.slow_weight)
            batch = {**batch, "weight": jax.lax.stop_gradient(weight)}
        return super().loss_terms(batch, scales)

    def quasi_newton_weights(self, batch: dict[str, Array]) -> Array | None:
        """With ``slow_weight = p > 0``: :func:`slow_window_weights` ``(B,)`` of the windows of
        ``batch`` under this model, which the trainer's quasi-Newton phases hold fixed (a weight
        that moved with the iterate, its derivative left out, would make the objective and its
        gradient disagree, and the line search fail); otherwise ``None``."""
        return _start_weights(self.eom, batch, self.slow_weight) if self.slow_weight > 0 else None

    def track_parameters(self, whole: bool = False) -> Any:
        """The output layers of the coefficient net and of the stream net (its MLP, where it has
        one), the constant ``c_l`` and the far-field flow's ``Q`` and ``b``: with a 64-wide net 331
        parameters, few enough for the whole-track fit's dense Gauss–Newton solve, and the ones
        the drag split and the flow's large-scale error move along (on issue 14's data, data
        seed 1, ``fhnn train``'s 20 iterations took ``c_l`` from 8.1 to 0.84 % off,
        ``docs/design/data/own_data_seed1_tracks20.json``). With ``whole``, besides these every
        parameter of both nets (17,355 at width 64), for the matrix-free iterations. ``None``
        for a flow that is not a :class:`StreamNet` or a coefficient law that is not a
        :class:`CoefficientNet`."""
        coef, flow = self.coefficients, self.flow
        if not isinstance(coef, CoefficientNet) or not isinstance(flow, StreamNet):
            return None
        free = jax.tree.map(lambda _: False, self)
        picks: list[Callable[[FHNN], Any]] = [
            lambda m: m.eom.coefficients.mlp.layers[-1].weight,
            lambda m: m.eom.coefficients.mlp.layers[-1].bias,
        ]
        if coef.c_l_raw is not None:
            picks.append(lambda m: m.eom.coefficients.c_l_raw)
        if coef.mass_raw is not None:
            picks.append(lambda m: m.eom.coefficients.mass_raw)
        if flow.mlp is not None:
            picks += [lambda m: m.eom.flow.mlp.layers[-1].weight, lambda m: m.eom.flow.mlp.layers[-1].bias]
        if flow.quadratic is not None and flow.linear is not None:
            picks += [lambda m: m.eom.flow.quadratic, lambda m: m.eom.flow.linear]
        for pick in picks:
            free = eqx.tree_at(pick, free, replace=True)
        if whole:
            nets: list[Callable[[FHNN], Any]] = [lambda m: m.eom.coefficients.mlp]
            if flow.mlp is not None:
                nets.append(lambda m: m.eom.flow.mlp)
            for pick in nets:
                free = eqx.tree_at(pick, free, replace=jax.tree.map(eqx.is_inexact_array, pick(self)))
        return free

    def warmup(self) -> tuple[FHNN, Callable[[FHNN], FHNN]] | None:
        """With a linear far field: the model without its stream MLP (the linear flow and the
        coefficient net), and putting the MLP back. The MLP starts with zero output weights, so the
        part predicts what the full model predicts, at a third of the cost per evaluation
        (value and gradient on 8,000 pairs: 0.068 s against 0.205 s for the whole model,
        ``benchmarks/training_speed.py``)."""
        flow = self.flow
        if not isinstance(flow, StreamNet) or flow.quadratic is None:
            return None
        mlp = flow.mlp
        part = eqx.tree_at(lambda m: m.eom.flow.mlp, self, None)

        def restore(fitted: FHNN) -> FHNN:
            return eqx.tree_at(lambda m: m.eom.flow.mlp, fitted, mlp, is_leaf=lambda x: x is None)

        return part, restore

    def regularization(self, states: Array, ts: Array) -> dict[str, Array]:
        """``{"flow": mean ‖Hψ_net‖²_F}`` at the batch positions, over the MLP part of ψ_θ (all of it
        when ``far_field="none"``); zero without a learned flow."""
        if not isinstance(self.flow, StreamNet):
            return {"flow": jnp.zeros(())}
        hess = jax.vmap(jax.jacrev(jax.grad(self.flow.net_stream)))(states[:, :2], ts)
        return {"flow": jnp.mean(jnp.sum(hess**2, axis=(1, 2)))}


def fhnn_arguments(dataset: Dataset) -> dict[str, Any]:
    """Data-derived arguments of :func:`build_fhnn`: the known body constants, whether the flow
    depends on time and has fluid inertia, and the input scales and radius range of the training
    split."""
    train = dataset.train
    body = dataset.constants()
    states = train.states[train.mask]  # (samples, 4): real samples only
    centre = dataset.centre
    pos = states[:, :2] - centre
    radius = np.hypot(pos[:, 0], pos[:, 1])
    raw = np.hypot(states[:, 0], states[:, 1])  # about the coordinate origin
    return {
        "mass": body["M"],
        "rho": body["rho"],
        "area": body["A"],
        "volume": body["V"],
        "time_dependent": dataset.time_dependent,
        "fluid_inertia": body["fluid_inertia"],
        "length_scale": float(np.sqrt(np.mean(np.sum(pos**2, axis=-1)))),
        "speed_scale": float(np.sqrt(np.mean(states[:, 2:] ** 2))),
        "time_scale": float(np.max(train.end_times)),
        "r_range": [float(radius.min()), float(radius.max())],
        "centre": [float(c) for c in centre],
        "about_origin": {
            "length_scale": float(np.sqrt(np.mean(raw**2))),
            "r_range": [float(raw.min()), float(raw.max())],
        },
    }


def build_fhnn(
    config: FHNNConfig,
    *,
    mass: float,
    rho: float,
    area: float,
    volume: float,
    time_dependent: bool,
    fluid_inertia: bool,
    length_scale: float,
    speed_scale: float,
    time_scale: float,
    key: Array,
    r_range: tuple[float, float] | None = None,
    centre: tuple[float, float] | None = None,
    about_origin: dict[str, Any] | None = None,
) -> FHNN:
    """An FHNN with fresh weights drawn from ``key``.

    Args:
        config: architecture (its ``time_dependent`` / ``fluid_inertia``, when set, override the
            arguments of the same name).
        mass, rho, area, volume: known body constants [kg, kg/m³, m², m³].
        time_dependent, fluid_inertia: defaults from the data set.
        length_scale: typical |x| [m] (input scaling of ψ_θ and of r).
        speed_scale: typical flow/relative speed [m/s] (scales ψ_θ's output and σ).
        time_scale: typical duration [s] (input scaling of t).
        r_range: (min, max) radius of the training positions [m]; used by ``r_extrapolation="hold"``
            where the coefficients are functions of r (``coefficients_in_r``).
        centre: the point [m] that ``r`` and the flow net's inputs are taken from with
            ``config.centre = "data"`` (None: the coordinate origin); ``length_scale`` and
            ``r_range`` are taken from it too.
        about_origin: ``length_scale`` and ``r_range`` taken from the coordinate origin,
            used in their place with ``config.centre = "origin"``.
        key: PRNG key.
    """
    k_flow, k_coef = jax.random.split(key)
    origin = _array(centre) if centre is not None and config.centre == "data" else None
    if config.centre == "origin" and about_origin is not None:
        length_scale, r_range = about_origin["length_scale"], about_origin["r_range"]
    act = _activation(config.effective_activation)
    depth = config.effective_depth
    if config.time_dependent is not None:
        time_dependent = config.time_dependent
    if config.fluid_inertia is not None:
        fluid_inertia = config.fluid_inertia
    flow: AbstractFlow
    if config.ablation == "no_flow":
        flow = StillWater()
    else:
        modes = config.time_modes if time_dependent else 0
        n_in = 3 if time_dependent and not modes else 2  # ξ, and τ in the paper's form
        mlp = eqx.nn.MLP(n_in, 1 + 2 * modes, config.width, depth, activation=act, key=k_flow)
        if config.far_field == "linear":  # the MLP starts at zero flow: docs/design/model.md
            mlp = eqx.tree_at(lambda m: m.layers[-1].weight, mlp, jnp.zeros_like(mlp.layers[-1].weight))
        flow = StreamNet(
            mlp=mlp,
            length_scale=_array(float(length_scale)),
            psi_scale=_array(float(speed_scale * length_scale)),
            time_scale=_array(float(time_scale)),
            uses_time=time_dependent,
            quadratic=jnp.zeros(3) if config.far_field == "linear" else None,
            linear=jnp.zeros(2) if config.far_field == "linear" else None,
            time_modes=modes,
            origin=origin,
        )
    mask = [1.0, 1.0, 1.0, 1.0]
    if config.ablation == "no_added_mass":
        mask[0] = mask[1] = 0.0
    if config.ablation == "no_linear_drag":
        mask[3] = 0.0
    coef_mlp = eqx.nn.MLP(2, 4, config.width, depth, activation=act, key=k_coef)
    # start the coefficients near init_coefficients: small last-layer weights, bias at the inverse map
    caps = np.asarray(config.caps)
    bias = uncap(np.asarray(config.init_coefficients), caps, config.cap_map)
    last = coef_mlp.layers[-1]
    last = eqx.tree_at(lambda l: (l.weight, l.bias), last, (last.weight * 0.1, jnp.asarray(bias)))
    coef_mlp = eqx.tree_at(lambda m: m.layers[-1], coef_mlp, last)
    coefficients = CoefficientNet(
        mlp=coef_mlp,
        caps=tuple(float(c) for c in caps),
        cap_map=config.cap_map,
        mask=_array(mask),
        r_scale=_array(float(length_scale)),
        sigma_scale=_array(float(max(speed_scale, 1e-6))),
        c_l_raw=jnp.asarray(bias[3]) if config.linear_drag == "constant" else None,
        mass_raw=jnp.asarray(bias[:2]) if config.added_mass == "constant" else None,
        r_range=(
            _array(r_range)
            if r_range is not None and config.r_extrapolation == "hold" and config.coefficients_in_r
            else None
        ),
        uses_r=config.coefficients_in_r,
    )
    # the body's constants as arrays too (EquationsOfMotion never differentiates them): one
    # compiled program serves every body and data set of the same architecture
    eom = EquationsOfMotion(
        flow=flow,
        coefficients=coefficients,
        mass=_array(float(mass)),
        rho=_array(float(rho)),
        area=_array(float(area)),
        volume=_array(float(volume)),
        fluid_inertia=fluid_inertia,
        origin=origin,
    )
    return FHNN(eom=eom, slow_weight=float(config.slow_weight))
