"""Intervals from the whole-track fit's curvature (Laplace, Gauss–Newton) and how much of each
rests on directions of the model's parameters that the data barely constrain.

Near the fit's minimum the sum of squared position residuals is the quadratic form of the
Gauss–Newton matrix ``H = JᵀJ`` in the fitted parameters (the start states eliminated,
:meth:`~fhnn.training.tracks.TrackFit.gauss_newton`). With independent position errors of
variance ``s²`` per coordinate, estimated from the residuals, the parameters' covariance is
``s² H⁻¹`` and a quantity ``q(θ)`` (a coefficient's median over the covered ``(r, σ)``) has the
standard deviation ``s·√(gᵀH⁻¹g)``, ``g = ∂q/∂θ``. The interval is conditional on what the fit
holds (the nets' hidden layers) and on the model's structure: it holds the data's noise, not a
bias.

``H`` is scaled to a unit diagonal; its eigenvalues below ``floor`` times the largest (default
:data:`FLOOR`) are raised to that level. Directions below it are ones the data barely constrain
(with a wide net, most of them: collinear features, the ``c_l``/``c_q`` trade at slow speeds;
without known forcing, masses and drag scaled together); a quantity whose variance comes mostly
from them has an interval that rests on the floor, and says so (``weak``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import numpy as np
from scipy.stats import norm

from fhnn.data.dataset import Split
from fhnn.models.base import AbstractVectorField
from fhnn.training.tracks import TrackFit

Array = jax.Array

#: The floor of the unit-diagonal Gauss–Newton matrix's eigenvalues, relative to the largest: a
#: direction less curved counts as curved this much (float64 resolves about 1e-15). The smallest
#: floor the calibration compared: none of them held every quantity's truth in 9 of 10 choosing
#: data sets (the design note "Intervals from curvature").
FLOOR = 1e-16
#: Eigenvalues of the unit-diagonal Gauss–Newton matrix below this share of the largest are not
#: resolved: float64 rounding in forming and decomposing a matrix of a few hundred rows leaves
#: errors of about that size, so an exactly flat direction (masses without forcing) shows there.
RESOLVED = 1e-14
#: The share of a quantity's variance from directions below the floor or unresolved
#: (:data:`RESOLVED`) past which its interval rests on the floor rather than on the data
#: (``weak``).
WEAK_SHARE = 0.5


@dataclass(frozen=True)
class Curvature:
    """The whole-track objective's curvature at a model.

    Attributes:
        theta: the fitted parameters ``(p,)``.
        model_at: the model at parameters ``θ`` ``(p,)`` (differentiable in ``θ``).
        scale: ``√diag(H)`` ``(p,)`` (1 where a parameter has no effect).
        values: eigenvalues of the unit-diagonal ``H`` ``(p,)``, ascending.
        vectors: its eigenvectors ``(p, p)`` (columns).
        noise_var: the residual variance per coordinate ``s²`` [m²].
        dof: the residuals' degrees of freedom (residuals − parameters − 4 per track).
    """

    theta: np.ndarray
    model_at: Callable[[Array], AbstractVectorField]
    scale: np.ndarray
    values: np.ndarray
    vectors: np.ndarray
    noise_var: float
    dof: int

    def intervals(
        self,
        quantities: Callable[[AbstractVectorField], Array],
        level: float = 0.9,
        floor: float = FLOOR,
    ) -> dict[str, np.ndarray]:
        """Laplace intervals of ``quantities(model)`` ``(q,)``.

        Args:
            quantities: the quantities as a function of the model (traceable by JAX).
            level: the intervals' level (two-sided, normal quantile).
            floor: the eigenvalue floor, relative to the largest eigenvalue.

        Returns:
            ``value``, ``sd``, ``lo``, ``hi`` ``(q,)``; ``floor_share`` ``(q,)``, the share of
            each variance from directions below the floor or unresolved (:data:`RESOLVED`);
            ``weak`` ``(q,)`` (bool), that share above :data:`WEAK_SHARE`; and ``determined``
            ``(q,)`` (bool), the interval narrower than ``±|value|`` (a wider one does not fix
            even the quantity's scale).
        """
        value = np.asarray(quantities(self.model_at(self.theta)))
        grad = np.asarray(jax.jacrev(lambda th: quantities(self.model_at(th)))(self.theta))
        along = (grad / self.scale) @ self.vectors  # (q, p): the gradient in the eigenbasis
        top = max(float(self.values[-1]), 0.0)
        level_floor = floor * top
        below = self.values < max(floor, RESOLVED) * top
        parts = along**2 / np.maximum(self.values, level_floor)
        total = parts.sum(axis=1)
        share = parts[:, below].sum(axis=1) / np.where(total > 0, total, 1.0)
        sd = np.sqrt(self.noise_var * total)
        half = norm.ppf(0.5 + level / 2) * sd
        return {
            "value": value,
            "sd": sd,
            "lo": value - half,
            "hi": value + half,
            "floor_share": share,
            "weak": share > WEAK_SHARE,
            "determined": half < np.abs(value),
        }


def track_curvature(model: AbstractVectorField, split: Split, free: object | None = None) -> Curvature:
    """The whole-track objective's curvature at ``model`` on the tracks of ``split``.

    Args:
        model: the fitted model (at the whole-track fit's minimum for the intervals to hold).
        split: the tracks the fit used (:func:`~fhnn.training.tracks.track_pieces` of the
            training split, as the fit cut them).
        free: the parameters taken as fitted (default: the model's
            :meth:`~fhnn.models.base.AbstractModel.track_parameters`).

    Raises:
        ValueError: where the model names no parameters for the whole-track fit, or the
            tracks hold no more residuals than parameters.
    """
    free = model.track_parameters() if free is None else free
    if free is None:
        raise ValueError(f"{type(model).__name__} names no parameters for the whole-track fit")
    fit = TrackFit(model, free, split)
    dof = fit.n - fit.p - 4 * fit.n_tracks
    if dof <= 0:
        raise ValueError(f"{fit.n} residuals cannot fix {fit.p} parameters and {fit.n_tracks} start states")
    h = fit.gauss_newton()
    diag = np.diag(h)
    scale = np.sqrt(np.where(diag > 0, diag, 1.0))
    values, vectors = np.linalg.eigh(h / np.outer(scale, scale))
    return Curvature(
        theta=np.asarray(fit.theta),
        model_at=fit.model_at,
        scale=scale,
        values=values,
        vectors=vectors,
        noise_var=float(fit.value) / dof,
        dof=dof,
    )


__all__ = ["FLOOR", "RESOLVED", "WEAK_SHARE", "Curvature", "track_curvature"]
