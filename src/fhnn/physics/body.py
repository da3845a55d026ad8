"""The floating body: known constants and hydrodynamic coefficient laws.

The equations of motion need four coefficients at each state, as functions of the rotation-invariant
scalars ``r = ‖x‖`` [m] and ``σ = ‖v_rel‖ + ε`` [m/s]:

    ``(m_ax, m_ay, c_q, c_l)`` — added masses [kg], quadratic drag coefficient [-], linear drag [N·s/m].

Anything that maps ``(r, σ)`` to these four is an :class:`AbstractCoefficients`; the ground truth is
:class:`CoefficientLaws` (one :class:`AbstractLaw` per coefficient), a learned model supplies a
neural network instead. Laws serialise to and from plain dictionaries (stored in data files as
``body_params``) so that a data set carries its own ground truth.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Any, ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from fhnn.errors import DataFormatError

Array = jax.Array

COEFFICIENT_NAMES = ("m_ax", "m_ay", "c_q", "c_l")


class AbstractLaw(eqx.Module):
    """A scalar coefficient as a function of ``(r, σ)``."""

    kind: ClassVar[str]

    @abc.abstractmethod
    def __call__(self, r: Array, sigma: Array) -> Array:
        """Coefficient value at distance ``r`` [m] and relative speed ``σ`` [m/s]."""

    def to_dict(self) -> dict[str, Any]:
        """``{"law": kind, <parameter>: value, ...}``."""
        out: dict[str, Any] = {"law": self.kind}
        for field in dataclasses.fields(self):
            out[field.name] = float(getattr(self, field.name))
        return out


class Constant(AbstractLaw):
    """A constant coefficient."""

    kind: ClassVar[str] = "constant"
    value: float

    def __call__(self, r: Array, sigma: Array) -> Array:
        return jnp.full(jnp.shape(sigma), self.value, dtype=jnp.result_type(sigma, float))


class ReynoldsDrag(AbstractLaw):
    """Reynolds-dependent quadratic drag ``c_q(σ) = c_inf + c_0 / (1 + σ/σ_ref)``."""

    kind: ClassVar[str] = "reynolds"
    c_inf: float
    c_0: float
    sigma_ref: float

    def __call__(self, r: Array, sigma: Array) -> Array:
        return self.c_inf + self.c_0 / (1.0 + sigma / self.sigma_ref)


class NearWallAddedMass(AbstractLaw):
    """Added mass growing near a cylinder of radius ``R`` at the origin.

    ``m_a(r) = m_inf (1 + strength (R/r)²)``.
    """

    kind: ClassVar[str] = "near_wall"
    m_inf: float
    radius: float
    strength: float

    def __call__(self, r: Array, sigma: Array) -> Array:
        return self.m_inf * (1.0 + self.strength * (self.radius / r) ** 2)


class TanhAddedMass(AbstractLaw):
    """Speed-dependent added mass ``m_a(σ) = base + amplitude · tanh(rate · σ)``."""

    kind: ClassVar[str] = "tanh"
    base: float
    amplitude: float
    rate: float

    def __call__(self, r: Array, sigma: Array) -> Array:
        return self.base + self.amplitude * jnp.tanh(self.rate * sigma)


LAWS: dict[str, type[AbstractLaw]] = {
    cls.kind: cls for cls in (Constant, ReynoldsDrag, NearWallAddedMass, TanhAddedMass)
}


def law_from_dict(spec: dict[str, Any]) -> AbstractLaw:
    """Rebuild a law from :meth:`AbstractLaw.to_dict` output (or a bare number: a constant)."""
    if isinstance(spec, int | float):
        return Constant(value=float(spec))
    if not isinstance(spec, dict) or "law" not in spec:
        raise DataFormatError(f"coefficient law must be a number or a dict with a 'law' key, got {spec!r}")
    kind = spec["law"]
    if kind not in LAWS:
        raise DataFormatError(f"unknown coefficient law {kind!r}; known: {', '.join(LAWS)}")
    cls = LAWS[kind]
    params = {k: v for k, v in spec.items() if k != "law"}
    expected = {field.name for field in dataclasses.fields(cls)}
    if set(params) != expected:
        raise DataFormatError(f"law {kind!r} needs parameters {sorted(expected)}, got {sorted(params)}")
    return cls(**{k: float(v) for k, v in params.items()})


class AbstractCoefficients(eqx.Module):
    """Maps ``(r, σ)`` to the four hydrodynamic coefficients ``(m_ax, m_ay, c_q, c_l)``."""

    @abc.abstractmethod
    def __call__(self, r: Array, sigma: Array) -> Array:
        """Coefficients at scalar ``r`` [m], ``σ`` [m/s]: shape ``(4,)`` in the order of
        :data:`COEFFICIENT_NAMES`."""


class CoefficientLaws(AbstractCoefficients):
    """Ground-truth coefficients, one analytic law each."""

    m_ax: AbstractLaw
    m_ay: AbstractLaw
    c_q: AbstractLaw
    c_l: AbstractLaw

    def __call__(self, r: Array, sigma: Array) -> Array:
        return jnp.stack([law(r, sigma) for law in self.laws()])

    def laws(self) -> tuple[AbstractLaw, ...]:
        return (self.m_ax, self.m_ay, self.c_q, self.c_l)


class Body(eqx.Module):
    """A rigid body translating in a fluid.

    Attributes:
        mass: dry mass M [kg].
        rho: fluid density ρ [kg/m³].
        area: reference area A [m²] of the quadratic drag.
        volume: displaced volume V [m³] (enters only the Morison inertia force ``ρV Du/Dt``).
        coefficients: the laws of ``(m_ax, m_ay, c_q, c_l)``.
        fluid_inertia: whether the Morison fluid-inertia force acts (the ``wave`` scenario).
    """

    mass: float
    rho: float
    area: float
    volume: float
    coefficients: CoefficientLaws
    fluid_inertia: bool = eqx.field(static=True, default=False)

    def to_dict(self) -> dict[str, Any]:
        """The ``body_params`` metadata of a data set (docs/spec.md §3)."""
        c = self.coefficients
        return {
            "M": float(self.mass),
            "rho": float(self.rho),
            "A": float(self.area),
            "V": float(self.volume),
            "m_ax": c.m_ax.to_dict(),
            "m_ay": c.m_ay.to_dict(),
            "c_q": c.c_q.to_dict(),
            "c_l": c.c_l.to_dict(),
            "fluid_inertia": bool(self.fluid_inertia),
        }

    @classmethod
    def from_dict(cls, spec: dict[str, Any]) -> Body:
        """Inverse of :meth:`to_dict`."""
        missing = [k for k in ("M", "rho", "A", "m_ax", "m_ay", "c_q", "c_l") if k not in spec]
        if missing:
            raise DataFormatError(f"body_params lacks {', '.join(missing)}")
        return cls(
            mass=float(spec["M"]),
            rho=float(spec["rho"]),
            area=float(spec["A"]),
            volume=float(spec.get("V", float(spec["M"]) / float(spec["rho"]))),
            coefficients=CoefficientLaws(
                m_ax=law_from_dict(spec["m_ax"]),
                m_ay=law_from_dict(spec["m_ay"]),
                c_q=law_from_dict(spec["c_q"]),
                c_l=law_from_dict(spec["c_l"]),
            ),
            fluid_inertia=bool(spec.get("fluid_inertia", False)),
        )
