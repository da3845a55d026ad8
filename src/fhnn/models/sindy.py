"""SINDy (Brunton et al. 2016) through PySINDy: sparse polynomial regression of ``ṡ`` on ``(s, F_ext)``.

The library is PySINDy's ``PolynomialLibrary`` of degree ``degree`` in the six inputs
``(x, y, vx, vy, Fx, Fy)``; sequentially thresholded least squares (``STLSQ``) fits the stored
derivatives of the training split. The fitted model becomes a JAX vector field
(:class:`SINDyField`), so it is rolled out and scored by the same evaluator as every other model.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from fhnn.config import Config, check_nonnegative, check_positive, frozen_config
from fhnn.data.dataset import Split
from fhnn.models.base import AbstractVectorField

Array = jax.Array
N_INPUTS = 6
INPUT_NAMES = ["x", "y", "vx", "vy", "Fx", "Fy"]


@frozen_config
class SINDyConfig(Config):
    """Polynomial degree, STLSQ threshold and ridge weight."""

    config_name = "sindy"

    degree: int = 3
    threshold: float = 1e-3
    alpha: float = 1e-8

    def validate(self) -> None:
        check_positive(self, "degree")
        check_nonnegative(self, "threshold", "alpha")


class SINDyField(AbstractVectorField):
    """``ṡ = Ξ θ(s, F)`` with monomials ``θ_k = Π_j u_j^{P_kj}``, ``u = (s, F)``."""

    coefficients: Array  # (4, K)
    powers: Array  # (K, 6), integer exponents stored as floats

    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        u = jnp.concatenate([state, force])
        features = jnp.prod(jnp.where(self.powers > 0, u[None, :] ** self.powers, 1.0), axis=1)
        return self.coefficients @ features


def _library(config: SINDyConfig):
    import pysindy as ps

    return ps.PolynomialLibrary(degree=config.degree, include_bias=True)


def library_powers(config: SINDyConfig) -> np.ndarray:
    """The exponent matrix ``(K, 6)`` of the polynomial library."""
    lib = _library(config)
    lib.fit(np.zeros((2, N_INPUTS)))
    return np.asarray(lib.powers_, dtype=float)


def empty_sindy(config: SINDyConfig) -> SINDyField:
    powers = library_powers(config)
    return SINDyField(coefficients=jnp.zeros((4, powers.shape[0])), powers=jnp.asarray(powers))


def fit_sindy(config: SINDyConfig, train: Split) -> tuple[SINDyField, list[str]]:
    """Fit on the observed states, forces and stored derivatives of ``train``.

    Returns the field and PySINDy's printed equations (one string per state component).
    """
    import pysindy as ps

    model = ps.SINDy(
        optimizer=ps.STLSQ(threshold=config.threshold, alpha=config.alpha),
        feature_library=_library(config),
    )
    n = train.sample_counts
    xs = [np.asarray(s[:k]) for s, k in zip(train.states, n, strict=True)]
    us = [np.asarray(f[:k]) for f, k in zip(train.forces, n, strict=True)]
    xdots = [np.asarray(d[:k]) for d, k in zip(train.derivs, n, strict=True)]
    ts = [np.asarray(t[:k]) for t, k in zip(train.times, n, strict=True)]
    model.fit(xs, t=ts, x_dot=xdots, u=us, feature_names=INPUT_NAMES)
    powers = np.asarray(model.feature_library.powers_, dtype=float)
    field = SINDyField(coefficients=jnp.asarray(model.coefficients()), powers=jnp.asarray(powers))
    equations = [str(e) for e in model.equations()]
    return field, equations


__all__ = ["SINDyConfig", "SINDyField", "empty_sindy", "fit_sindy", "library_powers"]
