"""Whole-track fit: Levenberg–Marquardt on every training track's positions at once.

Windows of a few seconds hold little on how the drag splits between its linear and quadratic
parts (``c_l`` is the σ → 0 limit of the total drag, which the tracks' long-time behaviour
tells); whole tracks hold it, but along a valley so flat that first-order fits do not move along
it (L-BFGS on whole tracks hardly moves ``c_l``). This phase solves the Gauss–Newton normal equations instead,
on a subspace a dense solve can afford — the parameters the model names
(:meth:`~fhnn.models.base.AbstractModel.track_parameters`; FHNN: the output layers of both nets,
the constant ``c_l`` and the far-field flow) — together with every track's start state
``(x, y, vx, vy)``, which the fit owns (the tracks begin at noisy positions and estimated
velocities). The objective is the sum of squared position residuals over all real samples, each
track rolled out from its start state by RK4, one step per sample interval, with the recorded
forcing.

The Jacobian in the model's parameters comes by forward mode in chunks of
:data:`TANGENT_CHUNK` tangents over batches of tracks, the start states' by forward mode per
track (a 4-column block each); the normal equations are reduced to the model's parameters by the
Schur complement of the start states' 4×4 blocks, so memory grows with the number of parameters
squared, not with the data. Marquardt's damping ``λ·diag(JᵀJ)`` rises ×4 on a rejected step and
falls ×3 on an accepted one.

Where the parameters are too many for that (every weight of both nets,
:meth:`TrackFit.step_matrix_free`), each step is solved without forming ``JᵀJ``: lineax's
conjugate gradients on the normal equations reduced by the same start-state blocks, each product
one Jacobian-vector product and its transpose through every track's rollout, so an iteration
costs the same whatever the number of parameters.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
from jax.flatten_util import ravel_pytree

from fhnn.data.dataset import Split, within_intervals
from fhnn.models.base import AbstractVectorField
from fhnn.physics.actuation import actuation_force, forcing
from fhnn.physics.integrators import rk4_solve, rk4_solve_held

Array = jax.Array

#: Forward-mode tangents evaluated together when building the Jacobian.
TANGENT_CHUNK = 64
#: Tracks whose Jacobian is built and reduced together (bounds the memory of one batch).
TRACK_BATCH = 64
#: First Marquardt damping, relative to the diagonal of ``JᵀJ``.
DAMPING_START = 1e-3
#: Damping past which an iteration gives up (no step lowers the objective).
DAMPING_MAX = 1e8
#: First damping of the matrix-free iterations (``λ·I``), relative to the mean diagonal of the
#: reduced ``JᵀJ`` (estimated from random probes), as :data:`DAMPING_START` is to each diagonal
#: element in the dense iterations.
MATRIX_FREE_DAMPING = 1e-3
#: Samples of the longest piece a track is cut into when the fit must be cut down to its size
#: (:func:`track_pieces`): 25 s at 0.05 s, longer than issue 14's 20 s tracks, on which the
#: split was found.
TRACK_PIECE = 500
#: The validation forecasts that choose the fit's iterate (:class:`ForecastScore`): an origin
#: every ``ORIGIN_EVERY`` s of each track, a start state fitted to ``ORIGIN_HISTORY`` s from it,
#: scored over the ``ORIGIN_AHEAD`` s after — ``benchmarks/own_data.py``'s validation forecast.
ORIGIN_EVERY, ORIGIN_HISTORY, ORIGIN_AHEAD = 2.0, 1.0, 5.0


@dataclass
class TrackFitStep:
    """One Levenberg–Marquardt iteration: the model after it, the mean square position residual
    per axis [m²] after it, the damping used and whether the step was taken."""

    model: AbstractVectorField
    mean_square: float
    damping: float
    accepted: bool


class TrackFit:
    """Levenberg–Marquardt on whole tracks (see the module docstring).

    Args:
        model: the vector field to fit; ``free`` selects the parameters that move (a filter
            tree of ``model``, as :meth:`~fhnn.models.base.AbstractModel.track_parameters`).
        split: the tracks; each rolled out from a fitted start state over its own sample times.
        weights: each track's weight ``(N,)`` in the sum of squares (default: 1 each; a
            bootstrap member's trajectory weights, :func:`~fhnn.training.sampling.bootstrap_weights`).
        mask: the samples that count ``(N, T)`` (default: the split's real samples; a subset of
            them scores a part of each track, as :class:`ForecastScore` does).
    """

    def __init__(
        self,
        model: AbstractVectorField,
        free: object,
        split: Split,
        weights: np.ndarray | None = None,
        mask: np.ndarray | None = None,
    ) -> None:
        self._given = (split, weights, mask)
        params, self._static = eqx.partition(model, free)
        theta, self._unravel = ravel_pytree(params)
        self.theta = jnp.asarray(theta)
        self.p = int(theta.size)
        self._t = jnp.asarray(split.times)
        self._obs = jnp.asarray(split.states[..., :2])
        self._mask = jnp.asarray(split.mask if mask is None else mask & split.mask)
        w = np.ones(split.n_traj) if weights is None else np.asarray(weights, dtype=float)
        self._root_w = jnp.asarray(np.sqrt(w))
        self._act = jnp.asarray(split.actuation)
        self._res = jnp.asarray(split.force_residual)
        # held forcing's change times (for interpolated forcing the times, unread)
        self._switch = jnp.asarray(split.times if split.switch is None else split.switch)
        self.n = 2 * int(np.asarray(self._mask).sum())
        self.n_tracks = split.n_traj
        #: Each track's start state ``(N, 4)``: the split's first state, refined by the fit.
        self.z = jnp.asarray(split.states[:, 0])
        self.damping = DAMPING_START
        #: The parameters whose Jacobian column is not zero (``None`` until the first iteration).
        self.live: np.ndarray | None = None
        self._kept: list[tuple[slice, np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._matrix_free: tuple[Callable[..., Array], ...] | None = None
        self._mf_damping = self._mf_first = 0.0
        resid, self._jz, self._jtheta = _programs(self._static, self._unravel, split.switch is not None)
        self._resid = resid
        self._cost = jax.jit(lambda th, z, *tr: jnp.sum(resid(th, z, *tr) ** 2))
        self.z = self._fit_starts(4)
        self.value = self._total_cost(self.theta, self.z)

    def freeing(self, free: object) -> TrackFit:
        """The same fit (tracks, weights, start states) at the current model with the parameters
        ``free`` moving instead."""
        other = TrackFit(self.model, free, *self._given)
        other.z = self.z
        other.value = other._total_cost(other.theta, other.z)
        return other

    @property
    def model(self) -> AbstractVectorField:
        return self.model_at(self.theta)

    def model_at(self, theta: Array) -> AbstractVectorField:
        """The model with its free parameters set to ``theta`` ``(p,)`` (traceable: a function of
        ``theta`` that JAX can differentiate)."""
        return eqx.combine(self._unravel(theta), self._static)

    def gauss_newton(self) -> np.ndarray:
        """The Gauss–Newton matrix ``JᵀJ`` of the objective in the model's parameters at the
        current iterate with the start states eliminated (the Schur complement of their 4×4
        blocks: the curvature left once every start state has adapted), ``(p, p)`` [m²/unit²]."""
        h_tt, _, h_tz, h_zz, _ = self._normal_equations()
        inv_zt = np.linalg.solve(h_zz + _jitter(h_zz), np.transpose(h_tz, (0, 2, 1)))
        reduced = h_tt - np.einsum("npi,niq->pq", h_tz, inv_zt)
        return 0.5 * (reduced + reduced.T)

    @property
    def mean_square(self) -> float:
        """Mean square position residual per axis [m²] at the current iterate (each track's
        squares times its weight)."""
        return self.value / self.n

    def rescore(self, theta: Array) -> float:
        """:attr:`mean_square` at the model's parameters ``theta`` (of the same structure) with
        the start states refitted to them (four Gauss–Newton steps from the last ones): how
        another fit's iterate explains these tracks, e.g. held-out ones."""
        self.theta = jnp.asarray(theta)
        self.z = self._fit_starts(4)
        self.value = self._total_cost(self.theta, self.z)
        return self.mean_square

    def sum_of_squares(self, theta: Array, z: Array, mask: Array | None = None) -> float:
        """The objective [m²] at the model's parameters ``theta`` and start states ``z`` ``(N, 4)``,
        over the samples ``mask`` ``(N, T)`` where given (another part of the same tracks, as
        :class:`ForecastScore` scores the forecasts after the histories it fits)."""
        theta, z = jnp.asarray(theta), jnp.asarray(z)
        if mask is None:
            return self._total_cost(theta, z)
        total = 0.0
        for b in self._batches():
            t, act, res, _, obs, root_w, switch = self._tracks(b)
            total += float(self._cost(theta, z[b], t, act, res, mask[b], obs, root_w, switch))
        return total

    def _tracks(self, rows: slice) -> tuple[Array, ...]:
        return (
            self._t[rows],
            self._act[rows],
            self._res[rows],
            self._mask[rows],
            self._obs[rows],
            self._root_w[rows],
            self._switch[rows],
        )

    def _batches(self) -> list[slice]:
        return [slice(i, min(i + TRACK_BATCH, self.n_tracks)) for i in range(0, self.n_tracks, TRACK_BATCH)]

    def _total_cost(self, theta: Array, z: Array) -> float:
        return float(sum(self._cost(theta, z[b], *self._tracks(b)) for b in self._batches()))

    def _fit_starts(self, iterations: int) -> Array:
        """The start states after ``iterations`` Gauss–Newton steps with the model held."""
        z = self.z
        for _ in range(iterations):
            parts = []
            for b in self._batches():
                tr = self._tracks(b)
                jz = self._jz(self.theta, z[b], *tr).reshape(-1, tr[0].shape[1] * 2, 4)
                r = self._resid(self.theta, z[b], *tr).reshape(jz.shape[0], -1)
                h = jnp.einsum("nki,nkj->nij", jz, jz)
                g = jnp.einsum("nki,nk->ni", jz, r)
                h = h + _jitter(h)
                parts.append(z[b] - jnp.linalg.solve(h, g[..., None])[..., 0])
            z = jnp.concatenate(parts)
        return z

    def _normal_equations(self, keep: bool = False) -> tuple[np.ndarray, ...]:
        """``(H_θθ, g_θ, H_θz, H_zz, g_z)`` of the Gauss–Newton system at the current iterate:
        ``(p, p)``, ``(p,)``, ``(N, p, 4)``, ``(N, 4, 4)``, ``(N, 4)``.

        Only the parameters whose Jacobian column was not zero at the first call get tangents
        (:attr:`live`): a parameter that moves no residual at all (an output the model
        overrides, such as the coefficient net's ``c_l`` beside the constant one) stays without
        effect while only the fitted parameters move, and its rows stay zero. The live tangents
        are spread evenly over the fewest chunks of at most :data:`TANGENT_CHUNK`. With ``keep``
        the Jacobian's blocks are kept for chord steps (:meth:`step`)."""
        p = self.p
        live = np.arange(p) if self.live is None else self.live
        m = live.size
        chunks = max(1, -(-m // TANGENT_CHUNK))
        size = -(-m // chunks)
        basis = jnp.zeros((chunks * size, p)).at[np.arange(m), live].set(1.0)
        h_tt, g_t = np.zeros((p, p)), np.zeros(p)
        h_tz, h_zz, g_z = [], [], []
        self._kept = [] if keep else None
        for b in self._batches():
            tr = self._tracks(b)
            r = np.asarray(self._resid(self.theta, self.z[b], *tr)).reshape(tr[0].shape[0], -1)
            jt = np.concatenate(
                [
                    np.asarray(self._jtheta(self.theta, self.z[b], basis[i : i + size], *tr))
                    for i in range(0, chunks * size, size)
                ]
            )[:m].reshape(m, r.shape[0], -1)  # (live, tracks, samples·2)
            jz = np.asarray(self._jz(self.theta, self.z[b], *tr)).reshape(r.shape[0], -1, 4)
            flat = jt.reshape(m, -1)
            h_tt[np.ix_(live, live)] += flat @ flat.T
            g_t[live] += flat @ r.ravel()
            block = np.zeros((r.shape[0], p, 4))
            block[:, live] = np.einsum("pnk,nki->npi", jt, jz, optimize=True)
            h_tz.append(block)
            h_zz.append(np.einsum("nki,nkj->nij", jz, jz, optimize=True))
            g_z.append(np.einsum("nki,nk->ni", jz, r, optimize=True))
            if self._kept is not None:
                self._kept.append((b, live, jt, jz))
        if self.live is None:
            self.live = np.flatnonzero(np.diag(h_tt) > 0)
        return h_tt, g_t, np.concatenate(h_tz), np.concatenate(h_zz), np.concatenate(g_z)

    def step(self, chord: int = 0) -> TrackFitStep:
        """One Levenberg–Marquardt iteration: the damped normal equations, reduced to the model's
        parameters (the start states' blocks eliminated), solved at rising damping until a step
        lowers the objective (or the damping passes :data:`DAMPING_MAX`: not taken); then up to
        ``chord`` chord steps — the same matrix and damping, the gradient at the new point from
        the same Jacobian (a residual evaluation, not a Jacobian) — each kept while it lowers
        the objective."""
        system = self._normal_equations(keep=chord > 0)
        h_tt, _, _, h_zz, _ = system
        # Marquardt's scaling: the diagonal of JᵀJ, 1 where a parameter has no effect at all
        d_t, d_z = np.diag(h_tt), np.diagonal(h_zz, axis1=1, axis2=2)
        scale = (np.where(d_t > 0, d_t, 1.0), np.where(d_z > 0, d_z, 1.0))
        while self.damping <= DAMPING_MAX:
            lam = self.damping
            if self._try(system, scale, lam):
                self.damping = max(lam / 3.0, 1e-12)
                for _ in range(chord):
                    g_t, g_z = self._chord_gradient()
                    if not self._try((system[0], g_t, system[2], system[3], g_z), scale, lam):
                        break
                self._kept = None
                return TrackFitStep(self.model, self.mean_square, lam, True)
            self.damping *= 4.0
        self._kept = None
        return TrackFitStep(self.model, self.mean_square, self.damping, False)

    def step_matrix_free(self, cg_steps: int) -> TrackFitStep:
        """One Levenberg–Marquardt iteration solved without forming ``JᵀJ``: ``(JᵀPJ + λI) δθ =
        −JᵀPr`` by ``cg_steps`` conjugate-gradient products (lineax; fewer only where it converges
        exactly; ``P`` projects out
        each track's start-state directions, so the start states are eliminated as in
        :meth:`step`), the start states then moved to their Gauss–Newton optimum under ``δθ``;
        at rising damping (×4) until a step lowers the objective, or not taken where the damping
        passes :data:`DAMPING_MAX` times its first value. Every track is in one program: its
        memory grows with the samples held (:func:`track_pieces` bounds them)."""
        if self._matrix_free is None:
            self._matrix_free = _matrix_free_programs(self._resid, self._jz, self.z.shape[0], cg_steps)
            scale, _ = self._matrix_free
            tracks = self._tracks(slice(None))
            self._mf_damping = MATRIX_FREE_DAMPING * float(scale(self.theta, self.z, *tracks))
            self._mf_first = self._mf_damping
        _, solve = self._matrix_free
        tracks = self._tracks(slice(None))
        while self._mf_damping <= DAMPING_MAX * self._mf_first:
            lam = self._mf_damping
            d_theta, d_z = solve(self.theta, self.z, jnp.asarray(lam), *tracks)
            theta, z = self.theta + d_theta, self.z + d_z
            value = self._total_cost(theta, z)
            if np.isfinite(value) and value < self.value:
                self.theta, self.z, self.value = theta, z, value
                self._mf_damping = lam / 3.0
                return TrackFitStep(self.model, self.mean_square, lam, True)
            self._mf_damping *= 4.0
        return TrackFitStep(self.model, self.mean_square, self._mf_damping, False)

    def _try(self, system: tuple[np.ndarray, ...], scale: tuple[np.ndarray, np.ndarray], lam: float) -> bool:
        """Solve the damped system at damping ``lam`` and take the step where it lowers the
        objective; whether it did."""
        h_tt, g_t, h_tz, h_zz, g_z = system
        d_t, d_z = scale
        a_zz = h_zz + lam * d_z[:, :, None] * np.eye(4)
        inv_tz = np.linalg.solve(a_zz, np.transpose(h_tz, (0, 2, 1)))  # (N, 4, p)
        inv_g = np.linalg.solve(a_zz, g_z[..., None])[..., 0]  # (N, 4)
        reduced = h_tt + lam * np.diag(d_t) - np.einsum("npi,niq->pq", h_tz, inv_tz)
        rhs = g_t - np.einsum("npi,ni->p", h_tz, inv_g)
        try:
            d_theta = -np.linalg.solve(reduced, rhs)
        except np.linalg.LinAlgError:
            return False
        d_z_step = -(inv_g + np.einsum("niq,q->ni", inv_tz, d_theta))
        theta, z = self.theta + jnp.asarray(d_theta), self.z + jnp.asarray(d_z_step)
        value = self._total_cost(theta, z)
        if np.isfinite(value) and value < self.value:
            self.theta, self.z, self.value = theta, z, value
            return True
        return False

    def _chord_gradient(self) -> tuple[np.ndarray, np.ndarray]:
        """``(g_θ, g_z)`` at the current iterate from the Jacobian kept by the last normal
        equations: ``(p,)``, ``(N, 4)``."""
        g_t, g_z = np.zeros(self.p), []
        for b, live, jt, jz in self._kept:
            tr = self._tracks(b)
            r = np.asarray(self._resid(self.theta, self.z[b], *tr)).reshape(jz.shape[0], -1)
            g_t[live] += jt.reshape(live.size, -1) @ r.ravel()
            g_z.append(np.einsum("nki,nk->ni", jz, r, optimize=True))
        return g_t, np.concatenate(g_z)


def _matrix_free_programs(
    resid: Callable[..., Array], jac_z: Callable[..., Array], n_tracks: int, cg_steps: int
) -> tuple[Callable[..., Array], ...]:
    """The compiled parts of :meth:`TrackFit.step_matrix_free`: the mean diagonal of the reduced
    ``JᵀPJ`` (its trace from four Rademacher probes, over ``p``), and the damped step
    ``(δθ, δz)`` at damping ``λ``."""

    def parts(theta: Array, z: Array, *tracks: Array) -> tuple:
        r, lin = jax.linearize(lambda th: resid(th, z, *tracks).reshape(n_tracks, -1), theta)
        back = jax.linear_transpose(lin, theta)
        jz = jac_z(theta, z, *tracks).reshape(n_tracks, -1, 4)  # (N, K, 4)
        hz = jnp.einsum("nki,nkj->nij", jz, jz)
        hz = hz + _jitter(hz)

        def project(u: Array) -> Array:  # (N, K): what the start states cannot absorb
            w = jnp.linalg.solve(hz, jnp.einsum("nki,nk->ni", jz, u)[..., None])[..., 0]
            return u - jnp.einsum("nki,ni->nk", jz, w)

        return r, lin, back, jz, hz, project

    def scale(theta: Array, z: Array, *tracks: Array) -> Array:
        _, lin, _, _, _, project = parts(theta, z, *tracks)
        probes = jax.random.rademacher(jax.random.PRNGKey(0), (4, theta.size), dtype=theta.dtype)
        return jnp.mean(jax.vmap(lambda v: jnp.sum(project(lin(v)) ** 2))(probes)) / theta.size

    def solve(theta: Array, z: Array, lam: Array, *tracks: Array) -> tuple[Array, Array]:
        r, lin, back, jz, hz, project = parts(theta, z, *tracks)
        op = lx.FunctionLinearOperator(
            lambda v: back(project(lin(v)))[0] + lam * v,
            jax.eval_shape(lambda: theta),
            lx.positive_semidefinite_tag,
        )
        rhs = -back(project(r))[0]
        # no tolerance: exactly ``cg_steps`` products (lineax's test is per element, and the
        # parameters that move no residual have zero there, which it reads as converged)
        d_theta = lx.linear_solve(op, rhs, lx.CG(rtol=0.0, atol=0.0, max_steps=cg_steps), throw=False).value
        moved = r + lin(d_theta)
        d_z = -jnp.linalg.solve(hz, jnp.einsum("nki,nk->ni", jz, moved)[..., None])[..., 0]
        return d_theta, d_z

    return jax.jit(scale), jax.jit(solve)


def _jitter(h: Array | np.ndarray) -> Array | np.ndarray:
    """A ridge of 1e-12 of each 4×4 block's trace ``(N, 4, 4)``: a start state that no sample
    constrains (a one-sample piece's velocity) stays solvable."""
    return 1e-12 * h.trace(axis1=1, axis2=2)[:, None, None] * np.eye(4)


def track_pieces(split: Split, budget: int, seed: int) -> tuple[Split, np.ndarray]:
    """The tracks of ``split`` cut down to a whole-track fit of at most ``budget`` samples
    (tracks × their padded length), so that one iteration's cost does not grow with the data.

    Where ``split`` fits the budget it is returned as it is. Otherwise each track longer than
    :data:`TRACK_PIECE` samples is cut into consecutive pieces of nearly equal length, none
    longer (every sample in one piece; each piece starts from its own first state, as a track
    does), and ``budget // L`` pieces are kept (``L`` the longest piece's length, at least one):
    one from each track in a seeded order before any track gives a second, so the pieces spread
    over the data. Returns the pieces as a :class:`~fhnn.data.dataset.Split` (absolute times
    kept, so the recorded forcing applies) and each piece's track in ``split`` ``(N',)``.

    Args:
        split: the tracks.
        budget: the most samples the fit may hold (≥ 1).
        seed: seed of the order in which pieces are kept.
    """
    counts = split.sample_counts
    if split.n_traj * split.n_times <= budget:
        return split, np.arange(split.n_traj)
    pieces = []  # (track, first sample, end sample)
    for i, n in enumerate(counts):
        cuts = np.rint(np.linspace(0, n, -(-int(n) // TRACK_PIECE) + 1)).astype(int)
        pieces.append([(i, a, b) for a, b in itertools.pairwise(cuts)])
    longest = max(b - a for track in pieces for _, a, b in track)
    rng = np.random.default_rng(seed)
    for track in pieces:
        rng.shuffle(track)
    order = rng.permutation(split.n_traj)
    rounds = range(max(map(len, pieces)))  # round r: each track's r-th piece, tracks in ``order``
    ranked = [pieces[i][r] for r in rounds for i in order if r < len(pieces[i])]
    kept = sorted(ranked[: max(1, budget // longest)])
    return _pieces(split, kept), np.asarray([i for i, _, _ in kept])


def fitted_pieces(split: Split, track_samples: int, seed: int) -> tuple[Split, np.ndarray]:
    """The pieces of ``split`` that the whole-track fit of a run trained with ``track_samples``
    and ``seed`` (its :class:`~fhnn.training.train_config.TrainConfig`'s) fits:
    :func:`track_pieces` with its seed."""
    return track_pieces(split, track_samples, seed + 5)


def _pieces(split: Split, kept: list[tuple[int, int, int]]) -> Split:
    """The samples ``a … b−1`` of track ``i`` of ``split`` for each ``(i, a, b)`` of ``kept``, as
    a :class:`~fhnn.data.dataset.Split` padded as a split is (absolute times, going on at the
    piece's mean step past its end; the rest repeating its last sample)."""
    times = split.times
    index = np.asarray([i for i, _, _ in kept])
    lengths = np.asarray([b - a for _, a, b in kept])
    longest = int(lengths.max())
    pad = np.minimum(np.arange(longest)[None, :], lengths[:, None] - 1)
    rows = np.asarray([a for _, a, _ in kept])[:, None] + pad
    t = times[index[:, None], rows]
    step = np.asarray([max((times[i, b - 1] - times[i, a]) / max(b - a - 1, 1), 1e-9) for i, a, b in kept])
    t = t + np.maximum(np.arange(longest)[None, :] - (lengths[:, None] - 1), 0) * step[:, None]
    take = lambda x: x[index[:, None], rows]  # noqa: E731
    return Split(
        t=t,
        states=take(split.states),
        states_clean=take(split.states_clean),
        derivs=take(split.derivs),
        forces=take(split.forces),
        actuation=split.actuation[index],
        lengths=lengths,
        switch=None if split.switch is None else within_intervals(t, take(split.switch)),
    )


def origin_pieces(split: Split, budget: int, seed: int) -> tuple[Split, np.ndarray]:
    """Forecast pieces of ``split``'s tracks: from an origin every :data:`ORIGIN_EVERY` s of each
    track (its first sample, then the first sample at or after each further step), the samples
    up to :data:`ORIGIN_HISTORY` + :data:`ORIGIN_AHEAD` s after it, where at least one sample
    lies beyond the history. Where they hold more than ``budget`` samples (pieces × the longest
    piece's length), a seeded subset of the origins is kept. Returns the pieces as a
    :class:`~fhnn.data.dataset.Split` and each piece's history mask ``(N', T')`` (its samples
    within :data:`ORIGIN_HISTORY` s of the origin); empty where no track has such an origin.

    Args:
        split: the tracks.
        budget: the most samples the pieces may hold (≥ 1).
        seed: seed of the subset kept.
    """
    span = ORIGIN_HISTORY + ORIGIN_AHEAD
    found = []  # (track, first sample, end sample)
    for i, n in enumerate(split.sample_counts):
        t = split.times[i, :n]
        for origin in np.arange(t[0], t[-1] - ORIGIN_HISTORY, ORIGIN_EVERY):
            a = int(np.searchsorted(t, origin - 1e-9))
            b = int(np.searchsorted(t, t[a] + span + 1e-9))
            if t[b - 1] > t[a] + ORIGIN_HISTORY + 1e-9:
                found.append((i, a, b))
    if not found:
        return split, np.zeros((0, 0), dtype=bool)
    longest = max(b - a for _, a, b in found)
    if len(found) * longest > budget:
        pick = np.random.default_rng(seed).choice(len(found), max(1, budget // longest), replace=False)
        found = [found[k] for k in np.sort(pick)]
    pieces = _pieces(split, found)
    history = pieces.mask & (pieces.times <= pieces.times[:, :1] + ORIGIN_HISTORY + 1e-9)
    return pieces, history


class ForecastScore:
    """How well a model forecasts held-out tracks as ``fhnn predict --history`` does: from each
    piece of :func:`origin_pieces`, the start state fitted to its first :data:`ORIGIN_HISTORY` s
    (four Gauss–Newton steps with the model held, from the last fit's), the RMS position error
    [m] over the :data:`ORIGIN_AHEAD` s after (``sqrt`` of the mean of ``|Δx|²``).

    Args:
        model: a model of the structure scored; ``free`` as :class:`TrackFit`'s.
        split: the held-out tracks.
        budget, seed: as :func:`origin_pieces`.
    """

    def __init__(
        self, model: AbstractVectorField, free: object, split: Split, budget: int, seed: int
    ) -> None:
        pieces, history = origin_pieces(split, budget, seed)
        self.n_forecasts = history.shape[0]
        if self.n_forecasts:
            self._history = TrackFit(model, free, pieces, mask=history)
            ahead = ~history & pieces.mask
            self._ahead, self._n_ahead = jnp.asarray(ahead), int(ahead.sum())

    def __call__(self, theta: Array) -> float:
        """The score at the model's parameters ``theta`` (NaN without forecasts)."""
        if not self.n_forecasts:
            return float("nan")
        self._history.rescore(theta)
        squares = self._history.sum_of_squares(theta, self._history.z, self._ahead)
        return float(np.sqrt(squares / self._n_ahead))


def _programs(
    static: object, unravel: Callable[[Array], object], held: bool
) -> tuple[Callable[..., Array], ...]:
    """The compiled residuals ``(B, T, 2)`` [m] of a batch of tracks (each times the square root
    of its track's weight; under held forcing, ``held``, RK4 steps split at each change), their
    Jacobian blocks in the
    start states ``(B, T, 2, 4)`` and Jacobian-vector products with a chunk of tangents in the
    model's parameters ``(C, B, T, 2)``."""

    def one(
        theta: Array,
        s0: Array,
        tt: Array,
        aa: Array,
        rr: Array,
        mk: Array,
        ob: Array,
        rw: Array,
        sw: Array,
    ) -> Array:
        model = eqx.combine(unravel(theta), static)
        if held:
            path = rk4_solve_held(lambda x, ti, u: model(x, ti, actuation_force(aa, ti) + u), s0, tt, rr, sw)
        else:
            path = rk4_solve(lambda x, ti: model(x, ti, forcing(aa, ti, tt, rr)), s0, tt)
        return rw * jnp.where(mk[:, None], path[:, :2] - ob, 0.0)

    axes = (None, 0, 0, 0, 0, 0, 0, 0, 0)

    def resid(theta: Array, z: Array, *tracks: Array) -> Array:
        return jax.vmap(one, in_axes=axes)(theta, z, *tracks)

    def jac_z(theta: Array, z: Array, *tracks: Array) -> Array:
        return jax.vmap(jax.jacfwd(one, argnums=1), in_axes=axes)(theta, z, *tracks)

    def jvp_theta(theta: Array, z: Array, tangents: Array, *tracks: Array) -> Array:
        push = lambda v: jax.jvp(lambda th: resid(th, z, *tracks), (theta,), (v,))[1]  # noqa: E731
        return jax.vmap(push)(tangents)

    return jax.jit(resid), jax.jit(jac_z), jax.jit(jvp_theta)
