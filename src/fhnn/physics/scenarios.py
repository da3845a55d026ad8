"""The named scenarios: flow, body and initial-state distribution, as typed objects.

Each scenario is a frozen configuration (:class:`Scenario`) whose fields are every parameter of its
flow, its body and its initial states; unknown names are rejected. It builds the ground-truth
:class:`~fhnn.physics.flows.AbstractFlow` and :class:`~fhnn.physics.body.Body`, draws initial
states from a NumPy generator, and carries the data-set defaults of docs/spec.md §3 (``defaults``).

>>> sc = get_scenario("steady_vortex", gamma=4.0)
>>> sc.flow()            # LambOseenVortex(gamma=4.0, core_radius=1.0, ...)
>>> sorted(SCENARIOS)    # the registry

A new scenario is a :class:`Scenario` subclass decorated with :func:`register_scenario` (the
units of any new parameter in :data:`UNITS`): ``fhnn scenarios``, ``fhnn simulate`` and the
reproduction's settings then know it.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from typing import Any, ClassVar, Literal

import jax
import jax.numpy as jnp
import numpy as np

from fhnn.config import Config, check_interval, check_nonnegative, check_positive, frozen_config
from fhnn.errors import ConfigError
from fhnn.physics.body import (
    Body,
    CoefficientLaws,
    Constant,
    NearWallAddedMass,
    ReynoldsDrag,
    TanhAddedMass,
)
from fhnn.physics.flows import (
    AbstractFlow,
    CylinderFlow,
    DeepWaterWave,
    FourierModes,
    LambOseenVortex,
    SolidBodyRotation,
    SuperposedFlow,
)

#: The unit of every scenario parameter, by name ("1": dimensionless).
UNITS = {
    "mass": "kg",
    "rho": "kg/m³",
    "area": "m²",
    "m_ax": "kg",
    "m_ay": "kg",
    "c_l": "N·s/m",
    "cq_inf": "1",
    "cq_0": "1",
    "cq_sigma_ref": "m/s",
    "gamma": "m²/s",
    "core_radius": "m",
    "r0_min": "m",
    "r0_max": "m",
    "v0_std": "m/s",
    "gamma_modulation": "1",
    "gamma_period": "s",
    "n_modes": "1",
    "k_min": "rad/m",
    "k_max": "rad/m",
    "mode_strength": "m²/s",
    "modes": "(rad/m, rad/m, rad, m²/s)",
    "x0_min": "m",
    "x0_max": "m",
    "y0_min": "m",
    "y0_max": "m",
    "stream_speed": "m/s",
    "radius": "m",
    "circulation": "m²/s",
    "wall_strength": "1",
    "min_distance_factor": "1",
    "amplitude": "m",
    "period": "s",
    "gravity": "m/s²",
    "omega": "1/s",
    "m_a_base": "kg",
    "m_a_amplitude": "kg",
    "m_a_rate": "s/m",
    "c_q": "1",
    "pos_range": "m",
    "vel_range": "m/s",
}


@dataclasses.dataclass(frozen=True)
class DatasetDefaults:
    """Default data-set settings of a scenario (docs/spec.md §2–3); every one can be overridden.

    Attributes:
        n_traj: number of trajectories over all splits.
        duration: length of train and val trajectories [s].
        test_duration: length of test trajectories [s] (long-horizon evaluation).
        dt: sampling interval [s].
        split: fractions (train, val, test) of the trajectories.
        actuation: "random" (sinusoidal forcing, docs/spec.md §1) or "none".
        obs_noise: standard deviation of the observation noise on stored states.
    """

    n_traj: int = 100
    duration: float = 20.0
    test_duration: float = 120.0
    dt: float = 0.05
    split: tuple[float, float, float] = (0.7, 0.2, 0.1)
    actuation: Literal["none", "random"] = "random"
    obs_noise: float = 0.0


@frozen_config
class Scenario(Config):
    """Base of all scenarios (abstract)."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    defaults: ClassVar[DatasetDefaults] = DatasetDefaults()

    @classmethod
    def describe(cls) -> str:
        return f"scenario {cls.name!r}"

    def flow(self) -> AbstractFlow:
        """The ground-truth background flow."""
        raise NotImplementedError

    def body(self) -> Body:
        """The ground-truth body."""
        raise NotImplementedError

    def sample_initial_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Draw ``n`` initial states ``(x, y, vx, vy)``, shape ``(n, 4)``."""
        raise NotImplementedError

    def resolve(self, rng: np.random.Generator) -> Scenario:
        """Draw the scenario's frozen random parts (if any) and return the completed scenario."""
        return self

    def rejected(self, states: np.ndarray) -> np.ndarray:
        """Which trajectories (states of shape ``(N, T, 4)``) must be redrawn; shape ``(N,)``."""
        return np.zeros(states.shape[0], dtype=bool)

    @property
    def time_dependent(self) -> bool:
        return self.flow().time_dependent


# --------------------------------------------------------------------------------------------
#: Every registered scenario class, by name, in the order registered.
SCENARIOS: dict[str, type[Scenario]] = {}


def register_scenario(cls: type[Scenario]) -> type[Scenario]:
    """Register scenario class ``cls`` under ``cls.name`` (a class decorator); returns it.

    Raises:
        ConfigError: a class without a name, or a name already registered by another class.
    """
    if not cls.name:
        raise ConfigError(f"scenario class {cls.__name__} has no name")
    if cls.name in SCENARIOS and SCENARIOS[cls.name] is not cls:
        raise ConfigError(f"a scenario named {cls.name!r} is already registered")
    SCENARIOS[cls.name] = cls
    return cls


# The body and initial states shared by the paper's five scenarios (docs/spec.md §1, §2.1)


@frozen_config
class _PaperBodyScenario(Scenario):
    mass: float = 10.0
    rho: float = 1000.0
    area: float = 0.02
    m_ax: float = 12.0
    m_ay: float = 20.0
    c_l: float = 3.0
    cq_inf: float = 0.6
    cq_0: float = 0.4
    cq_sigma_ref: float = 0.2

    def validate(self) -> None:
        check_positive(self, "mass", "rho", "area", "cq_sigma_ref")
        check_nonnegative(self, "m_ax", "m_ay", "c_l", "cq_inf", "cq_0")

    def _laws(self) -> CoefficientLaws:
        return CoefficientLaws(
            m_ax=Constant(value=self.m_ax),
            m_ay=Constant(value=self.m_ay),
            c_q=ReynoldsDrag(c_inf=self.cq_inf, c_0=self.cq_0, sigma_ref=self.cq_sigma_ref),
            c_l=Constant(value=self.c_l),
        )

    def body(self) -> Body:
        return self._body(self._laws())

    def _body(self, laws: CoefficientLaws, fluid_inertia: bool = False) -> Body:
        # V = M/ρ: neutrally buoyant (V enters only the Morison force of the wave scenario)
        return Body(
            mass=self.mass,
            rho=self.rho,
            area=self.area,
            volume=self.mass / self.rho,
            coefficients=laws,
            fluid_inertia=fluid_inertia,
        )


@frozen_config
class _BoxStartScenario(_PaperBodyScenario):
    """Initial positions uniform in a box, velocities Gaussian about a scenario-given mean."""

    x0_min: float = 0.0
    x0_max: float = 0.0
    y0_min: float = 0.0
    y0_max: float = 0.0
    v0_std: float = 0.0

    def validate(self) -> None:
        super().validate()
        check_nonnegative(self, "v0_std")
        check_interval(self, "x0_min", "x0_max")
        check_interval(self, "y0_min", "y0_max")

    def _mean_initial_velocity(self, pos: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def sample_initial_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        pos = np.column_stack(
            [rng.uniform(self.x0_min, self.x0_max, n), rng.uniform(self.y0_min, self.y0_max, n)]
        )
        vel = self._mean_initial_velocity(pos) + rng.normal(0.0, self.v0_std, (n, 2))
        return np.column_stack([pos, vel])


@frozen_config
class _VortexScenario(_PaperBodyScenario):
    gamma: float = 5.0
    core_radius: float = 1.0
    r0_min: float = 0.5
    r0_max: float = 3.0
    v0_std: float = 0.2

    def validate(self) -> None:
        super().validate()
        check_positive(self, "core_radius", "r0_max")
        check_nonnegative(self, "r0_min", "v0_std")
        check_interval(self, "r0_min", "r0_max")

    def sample_initial_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        r0 = rng.uniform(self.r0_min, self.r0_max, n)
        angle = rng.uniform(0.0, 2.0 * math.pi, n)
        v0 = rng.normal(0.0, self.v0_std, (n, 2))
        return np.column_stack([r0 * np.cos(angle), r0 * np.sin(angle), v0])

    def flow(self) -> AbstractFlow:
        return LambOseenVortex(gamma=self.gamma, core_radius=self.core_radius)


@register_scenario
@frozen_config
class SteadyVortex(_VortexScenario):
    """Lamb–Oseen vortex at the origin (docs/spec.md §2.1)."""

    name: ClassVar[str] = "steady_vortex"
    summary: ClassVar[str] = "Lamb–Oseen vortex at the origin"


@register_scenario
@frozen_config
class TimeVaryingVortex(_VortexScenario):
    """Lamb–Oseen vortex with ``Γ(t) = Γ0 (1 + m sin(2π t / period))`` (docs/spec.md §2.2)."""

    name: ClassVar[str] = "time_varying_vortex"
    summary: ClassVar[str] = "Lamb–Oseen vortex with a periodically varying circulation"

    gamma_modulation: float = 0.3
    gamma_period: float = 20.0

    def validate(self) -> None:
        super().validate()
        check_nonnegative(self, "gamma_modulation")
        check_positive(self, "gamma_period")

    def flow(self) -> AbstractFlow:
        return LambOseenVortex(
            gamma=self.gamma,
            core_radius=self.core_radius,
            modulation=self.gamma_modulation,
            period=self.gamma_period,
        )


Mode = tuple[float, float, float, float]


@register_scenario
@frozen_config
class NoisyFlow(_VortexScenario):
    """Vortex plus a frozen random divergence-free perturbation (docs/spec.md §2.3).

    ``ψ_n = Σ_j b_j cos(k_j·x + φ_j)`` with ``|k_j| ~ U(k_min, k_max)``, direction and φ_j uniform,
    ``b_j = mode_strength / |k_j|``. ``modes`` holds the drawn ``(kx, ky, phase, amp)``; it is drawn
    once per data set (:meth:`resolve`) unless given.
    """

    name: ClassVar[str] = "noisy_flow"
    summary: ClassVar[str] = "Lamb–Oseen vortex plus a frozen random perturbation, noisy observations"
    defaults: ClassVar[DatasetDefaults] = DatasetDefaults(obs_noise=1e-3)

    n_modes: int = 8
    k_min: float = 0.5
    k_max: float = 2.0
    mode_strength: float = 0.03
    modes: tuple[Mode, ...] | None = None

    def validate(self) -> None:
        super().validate()
        check_positive(self, "k_min", "k_max")
        check_nonnegative(self, "n_modes", "mode_strength")
        check_interval(self, "k_min", "k_max")
        if self.modes is not None and len(self.modes) != self.n_modes:
            raise ConfigError(
                f"{self.describe()}: {len(self.modes)} modes given but n_modes = {self.n_modes}"
            )

    def resolve(self, rng: np.random.Generator) -> NoisyFlow:
        if self.modes is not None:
            return self
        k = rng.uniform(self.k_min, self.k_max, self.n_modes)
        direction = rng.uniform(0.0, 2.0 * math.pi, self.n_modes)
        phase = rng.uniform(0.0, 2.0 * math.pi, self.n_modes)
        modes = tuple(
            (
                float(kj * math.cos(d)),
                float(kj * math.sin(d)),
                float(p),
                float(self.mode_strength / kj),
            )
            for kj, d, p in zip(k, direction, phase, strict=True)
        )
        return dataclasses.replace(self, modes=modes)

    def flow(self) -> AbstractFlow:
        if self.modes is None:
            raise ConfigError(f"{self.describe()}: modes not drawn yet; call resolve(rng) first")
        kx, ky, phase, amp = (jnp.asarray(c, float) for c in zip(*self.modes, strict=True))
        if self.n_modes == 0:
            return super().flow()
        return SuperposedFlow(parts=(super().flow(), FourierModes(kx=kx, ky=ky, phase=phase, amp=amp)))

    def to_dict(self) -> dict[str, Any]:
        out = super().to_dict()
        if self.modes is not None:
            out["modes"] = [{"kx": kx, "ky": ky, "phase": ph, "amp": a} for kx, ky, ph, a in self.modes]
        return out

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> NoisyFlow:
        values = dict(values)
        modes = values.get("modes")
        if isinstance(modes, str):
            modes = json.loads(modes)
        if isinstance(modes, list) and modes and isinstance(modes[0], Mapping):
            try:
                modes = [(m["kx"], m["ky"], m["phase"], m["amp"]) for m in modes]
            except KeyError as exc:
                raise ConfigError(f"noisy_flow mode lacks key {exc}") from None
        if modes is not None:
            values["modes"] = modes
        return super().from_dict(values)  # type: ignore[return-value]


@register_scenario
@frozen_config
class Obstacle(_BoxStartScenario):
    """Uniform stream past a cylinder with circulation; near-wall added mass (docs/spec.md §2.4)."""

    name: ClassVar[str] = "obstacle"
    summary: ClassVar[str] = "uniform stream past a cylinder with circulation"

    stream_speed: float = 0.3
    radius: float = 0.5
    circulation: float = 0.5
    wall_strength: float = 0.5
    x0_min: float = -4.0
    x0_max: float = -2.0
    y0_min: float = -1.5
    y0_max: float = 1.5
    v0_std: float = 0.1
    min_distance_factor: float = 1.1

    def validate(self) -> None:
        super().validate()
        check_positive(self, "radius", "min_distance_factor")
        check_nonnegative(self, "wall_strength")

    def flow(self) -> AbstractFlow:
        return CylinderFlow(stream_speed=self.stream_speed, radius=self.radius, circulation=self.circulation)

    def body(self) -> Body:
        near = lambda m: NearWallAddedMass(m_inf=m, radius=self.radius, strength=self.wall_strength)  # noqa: E731
        laws = self._laws()
        return self._body(
            CoefficientLaws(m_ax=near(self.m_ax), m_ay=near(self.m_ay), c_q=laws.c_q, c_l=laws.c_l)
        )

    def _mean_initial_velocity(self, pos: np.ndarray) -> np.ndarray:
        return np.broadcast_to(np.array([self.stream_speed, 0.0]), pos.shape)

    def rejected(self, states: np.ndarray) -> np.ndarray:
        r = np.sqrt(states[..., 0] ** 2 + states[..., 1] ** 2)
        too_close = np.min(np.where(np.isfinite(r), r, 0.0), axis=1) < self.min_distance_factor * self.radius
        return too_close | ~np.all(np.isfinite(states), axis=(1, 2))


@register_scenario
@frozen_config
class Wave(_BoxStartScenario):
    """Neutrally buoyant body under a deep-water wave, with Morison inertia (docs/spec.md §2.5)."""

    name: ClassVar[str] = "wave"
    summary: ClassVar[str] = "deep-water linear wave in a vertical plane, Morison inertia force"

    amplitude: float = 0.2
    period: float = 4.0
    gravity: float = 9.81
    x0_min: float = -5.0
    x0_max: float = 5.0
    y0_min: float = -3.0
    y0_max: float = -1.0
    v0_std: float = 0.05

    def validate(self) -> None:
        super().validate()
        check_positive(self, "period", "gravity")
        check_nonnegative(self, "amplitude")

    def flow(self) -> AbstractFlow:
        return DeepWaterWave(amplitude=self.amplitude, period=self.period, gravity=self.gravity)

    def body(self) -> Body:
        return self._body(self._laws(), fluid_inertia=True)

    def _mean_initial_velocity(self, pos: np.ndarray) -> np.ndarray:
        return np.asarray(jax.vmap(self.flow().velocity, in_axes=(0, None))(jnp.asarray(pos), 0.0))


@register_scenario
@frozen_config
class SolidBodyVortex(Scenario):
    """Solid-body rotation: the configuration of the paper's published code (docs/spec.md §2.6)."""

    name: ClassVar[str] = "solid_body_vortex"
    summary: ClassVar[str] = "solid-body rotation, the configuration of the paper's published code"
    defaults: ClassVar[DatasetDefaults] = DatasetDefaults(
        n_traj=64,
        duration=8.0,
        test_duration=120.0,
        dt=0.02,
        split=(0.7, 0.1, 0.2),
        actuation="none",
    )

    omega: float = 0.2
    mass: float = 100.0
    rho: float = 1000.0
    area: float = 1.0
    m_a_base: float = 30.0
    m_a_amplitude: float = 10.0
    m_a_rate: float = 0.2
    c_q: float = 0.8
    c_l: float = 5.0
    pos_range: float = 2.5
    vel_range: float = 0.9

    def validate(self) -> None:
        check_positive(self, "mass", "rho", "area")
        check_nonnegative(
            self, "m_a_base", "m_a_amplitude", "m_a_rate", "c_q", "c_l", "pos_range", "vel_range"
        )

    def flow(self) -> AbstractFlow:
        return SolidBodyRotation(omega=self.omega)

    def body(self) -> Body:
        added = TanhAddedMass(base=self.m_a_base, amplitude=self.m_a_amplitude, rate=self.m_a_rate)
        return Body(
            mass=self.mass,
            rho=self.rho,
            area=self.area,
            volume=self.mass / self.rho,
            coefficients=CoefficientLaws(
                m_ax=added, m_ay=added, c_q=Constant(value=self.c_q), c_l=Constant(value=self.c_l)
            ),
        )

    def sample_initial_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        pos = rng.uniform(-self.pos_range, self.pos_range, (n, 2))
        vel = rng.uniform(-self.vel_range, self.vel_range, (n, 2))
        return np.column_stack([pos, vel])


#: The five scenarios of the paper's scenario table (docs/spec.md §2.1–2.5).
PAPER_SCENARIOS = ("steady_vortex", "time_varying_vortex", "noisy_flow", "obstacle", "wave")


def scenario_class(name: str) -> type[Scenario]:
    """The registered scenario class called ``name``."""
    if name not in SCENARIOS:
        raise ConfigError(f"unknown scenario {name!r}; available: {', '.join(SCENARIOS)}")
    return SCENARIOS[name]


def get_scenario(name: str, **params: Any) -> Scenario:
    """Build scenario ``name`` with ``params`` (strings are converted to the field types)."""
    return scenario_class(name).from_dict(params)
