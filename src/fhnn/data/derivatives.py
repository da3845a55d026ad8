"""Noise levels and derivatives of irregularly sampled, noisy signals (imported measurements).

A user's table has positions (perhaps velocities) at irregular times with noise. Two estimates
make a data set of it:

- :func:`noise_level`: the observation noise's standard deviation, from how far each sample lies
  from the cubic through its two neighbours on either side, with the Lagrange weights of its own
  irregular neighbour times (exact for any cubic, so a smooth trajectory sampled finely adds almost
  nothing), pooled over every trajectory; a trajectory's axes count as one curve, so the estimate
  does not change when the table is turned.
- :func:`smooth_derivatives`: velocities and accelerations, by one of two estimators
  (:data:`SMOOTHERS`), both held to the noise level by the discrepancy principle (residuals no
  larger than the noise):

  - ``"spline"``: a quintic FITPACK smoothing spline; a trajectory's axes are one parametric curve
    with common knots (:func:`spline_derivatives`);
  - ``"kalman"``: a Kalman (Rauch–Tung–Striebel) smoother per trajectory and axis under a
    white-noise-jerk model, each interval's transition computed for its own length
    (:func:`kalman_derivatives`); every series runs at once, vectorised in chunks of
    :data:`CHUNK`.

The default, ``"auto"`` (:func:`choose_smoother`), is the spline up to :data:`AUTO_SPLINE_ROWS`
rows and the Kalman smoother above. What chose the estimators and the default:
design note ``docs/design/smoothers.md``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from fhnn.errors import ConfigError

#: Degree of :func:`spline_derivatives`.
SPLINE_DEGREE = 5
#: Series smoothed per compiled pass (bounds memory: ~130 bytes per sample and series).
CHUNK = 256
#: Grid of jerk intensities, as powers of ten relative to ``σ² / h⁵`` (h: the median step).
Q_GRID = np.arange(-8.0, 1.01, 0.25)
#: Series (at most) on which the intensity is chosen (× the grid's 37 intensities: two chunks).
Q_SERIES = 13


def lagrange_residuals(t: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Residuals of each interior sample from the cubic through its two neighbours either side,
    divided by their noise factor ``sqrt(1 + Σ w²)``: shape ``(n − 4,)`` for ``n ≥ 5`` samples at
    increasing times ``t`` [s]; empty for fewer. Pure noise of std ``σ`` gives residuals of std ``σ``."""
    t, z = np.asarray(t, dtype=float), np.asarray(z, dtype=float)
    if t.size < 5:
        return np.zeros(0)
    nodes = np.stack([t[:-4], t[1:-3], t[3:-1], t[4:]], axis=1)  # (n-4, 4)
    values = np.stack([z[:-4], z[1:-3], z[3:-1], z[4:]], axis=1)
    centre = t[2:-2, None]
    weights = np.ones_like(nodes)
    for j in range(4):
        for k in range(4):
            if k != j:
                weights[:, j] *= (centre[:, 0] - nodes[:, k]) / (nodes[:, j] - nodes[:, k])
    residual = z[2:-2] - np.sum(weights * values, axis=1)
    return residual / np.sqrt(1.0 + np.sum(weights**2, axis=1))


def robust_std(x: np.ndarray) -> float:
    """1.4826 × the median absolute deviation of ``x`` (the std for Gaussian ``x``; 0 if empty)."""
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def noise_level(series: list[tuple[np.ndarray, np.ndarray]]) -> float:
    """The observation noise's std [units of the signal] pooled over ``series``: a list of
    ``(t, z)`` pairs, each with increasing times ``t`` ``(n,)`` [s] and values ``z`` ``(n,)``.
    Consecutive series sharing one times array (a trajectory's axes) count as one curve in ``d``
    dimensions: its residual vectors' squared lengths, whose median is ``σ²`` times the median of
    χ² with ``d`` degrees of freedom for isotropic noise, give an estimate that does not change
    when the table is turned; lone series get :func:`robust_std` of their residuals."""
    from scipy.stats import chi2

    lone, squares = [], {}
    for t, zs in _curves(series):
        res = np.stack([lagrange_residuals(t, z) for z in zs], axis=1)  # (n - 4, d)
        if len(zs) == 1:
            lone.append(res[:, 0])
        else:
            squares.setdefault(len(zs), []).append(np.sum(res**2, axis=1))
    if not squares:
        return robust_std(np.concatenate([np.zeros(0), *lone]))
    if lone:
        raise ValueError("noise_level: give either curves or lone series, not both")
    (d, parts), *more = squares.items()
    if more:
        raise ValueError("noise_level: every curve must have the same number of axes")
    pooled = np.concatenate(parts)
    return float(np.sqrt(np.median(pooled) / chi2.ppf(0.5, d))) if pooled.size else 0.0


def _mm(a: jax.Array, b: jax.Array) -> jax.Array:
    """Product of stacks of 3 × 3 matrices laid out ``(3, 3, S)`` (series last, so every operation
    is an element-wise one over the series: batched 3 × 3 products and solves are far slower)."""
    return a[:, 0, None] * b[None, 0] + a[:, 1, None] * b[None, 1] + a[:, 2, None] * b[None, 2]


def _solve_spd(p: jax.Array, b: jax.Array) -> jax.Array:
    """``p⁻¹ b`` for stacks ``(3, 3, S)`` of symmetric positive-definite ``p`` and any ``b``, by a
    Cholesky factorisation written out entry by entry (backward stable: near the diffuse start
    ``p`` is nearly singular, where cofactors lose every digit)."""
    l00 = jnp.sqrt(p[0, 0])
    l10, l20 = p[1, 0] / l00, p[2, 0] / l00
    l11 = jnp.sqrt(p[1, 1] - l10 * l10)
    l21 = (p[2, 1] - l20 * l10) / l11
    l22 = jnp.sqrt(p[2, 2] - l20 * l20 - l21 * l21)
    y0 = b[0] / l00  # L y = b
    y1 = (b[1] - l10 * y0) / l11
    y2 = (b[2] - l20 * y0 - l21 * y1) / l22
    x2 = y2 / l22  # Lᵀ x = y
    x1 = (y1 - l21 * x2) / l11
    x0 = (y0 - l10 * x1 - l20 * x2) / l00
    return jnp.stack([x0, x1, x2])


def _transition(h: jax.Array, q: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Transition ``F`` and process noise ``Q`` (each ``(3, 3, S)``) over steps ``h`` ``(S,)`` of a
    white-noise-jerk model of intensity ``q`` ``(S,)``."""
    one, zero = jnp.ones_like(h), jnp.zeros_like(h)
    F = jnp.stack([jnp.stack([one, h, h * h / 2]), jnp.stack([zero, one, h]), jnp.stack([zero, zero, one])])
    Q = jnp.stack(
        [
            jnp.stack([h**5 / 20, h**4 / 8, h**3 / 6]),
            jnp.stack([h**4 / 8, h**3 / 3, h**2 / 2]),
            jnp.stack([h**3 / 6, h**2 / 2, h]),
        ]
    )
    return F, q * Q


@jax.jit
def rts_smooth(
    t: jax.Array, z: jax.Array, mask: jax.Array, noise: jax.Array, q: jax.Array, step: jax.Array
) -> jax.Array:
    """Smoothed ``(position, velocity, acceleration)`` ``(S, n, 3)`` of ``S`` series sampled at
    ``t`` ``(S, n)`` [s] (non-decreasing; a zero step is padding) with values ``z`` ``(S, n)``,
    observed where ``mask`` ``(S, n)`` (the first sample always), noise std ``noise``, jerk
    intensity ``q`` ``(S,)``. The first sample's velocity and acceleration start diffuse (a
    variance of 10⁶ σ² per power of the typical ``step`` [s]). The forward (Kalman) pass also
    gives each step's smoother gain ``G_k = P_k Fᵀ P⁻_{k+1}⁻¹``, so the backward pass is
    ``x̂_k = x_k + G_k (x̂_{k+1} − x⁻_{k+1})``."""
    S = z.shape[0]
    big = 1e6 * noise**2
    x0 = jnp.stack([z[:, 0], jnp.zeros(S), jnp.zeros(S)])
    P0 = jnp.diag(jnp.stack([noise**2, big / step**2, big / step**4]))[:, :, None] * jnp.ones(S)

    def forward(carry, inputs):
        x, P = carry
        h, zk, mk = inputs
        F, Q = _transition(h, q)
        xp = F[:, 0] * x[0] + F[:, 1] * x[1] + F[:, 2] * x[2]
        PFt = _mm(P, jnp.swapaxes(F, 0, 1))
        Pp = _mm(F, PFt) + Q
        gain = Pp[:, 0] / (Pp[0, 0] + noise**2) * mk
        xf = xp + gain * (zk - xp[0])
        Pf = Pp - gain[:, None] * Pp[0][None, :]
        Pf = 0.5 * (Pf + jnp.swapaxes(Pf, 0, 1))
        return (xf, Pf), (xp, xf, jnp.swapaxes(_solve_spd(Pp, jnp.swapaxes(PFt, 0, 1)), 0, 1))

    inputs = (jnp.diff(t, axis=1).T, z[:, 1:].T, mask[:, 1:].T)
    _, (xp, xf, G) = jax.lax.scan(forward, (x0, P0), inputs)

    def backward(xs, inputs):
        xf_prev, xp_k, G_prev = inputs  # filtered state at k - 1, prediction of k, gain of k - 1
        d = xs - xp_k
        x_prev = xf_prev + G_prev[:, 0] * d[0] + G_prev[:, 1] * d[1] + G_prev[:, 2] * d[2]
        return x_prev, x_prev

    xf_all = jnp.concatenate([x0[None], xf])
    _, xs = jax.lax.scan(backward, xf_all[-1], (xf_all[:-1], xp, G), reverse=True)
    return jnp.transpose(jnp.concatenate([xs, xf_all[-1][None]]), (2, 0, 1))


def _padded(series: list[tuple[np.ndarray, np.ndarray]], size: int) -> tuple[np.ndarray, ...]:
    """``series`` as ``(S, size)`` arrays: times (padding repeats the last: zero steps), values,
    mask."""
    S = len(series)
    t, z, mask = np.zeros((S, size)), np.zeros((S, size)), np.zeros((S, size))
    for i, (ti, zi) in enumerate(series):
        n = ti.size
        t[i, :n], t[i, n:] = ti, ti[-1]
        z[i, :n], z[i, n:] = zi, zi[-1]
        mask[i, :n] = 1.0
    return t, z, mask


def _smooth(
    series: list[tuple[np.ndarray, np.ndarray]], noise: float, q: np.ndarray, size: int
) -> list[np.ndarray]:
    """:func:`rts_smooth` of each series with its intensity ``q`` ``(S,)``, padded to ``size``
    samples: one ``(n_i, 3)`` array per series. Series go :data:`CHUNK` at a time, every chunk
    filled up to :data:`CHUNK` with copies of its first series, so that an import compiles one
    program; every chunk is dispatched before any result is read (JAX runs them asynchronously)."""
    pending = []
    for start in range(0, len(series), CHUNK):
        chunk = series[start : start + CHUNK]
        fill = CHUNK - len(chunk)
        qs = np.r_[q[start : start + CHUNK], np.full(fill, q[start])]
        t, z, mask = _padded([*chunk, *[chunk[0]] * fill], size)
        step = max(float(np.median(np.concatenate([np.diff(ti) for ti, _ in chunk]))), 1e-12)
        pending.append((chunk, rts_smooth(*(jnp.asarray(a) for a in (t, z, mask, noise, qs, step)))))
    out: list[np.ndarray] = []
    for chunk, smooth in pending:
        smooth = np.asarray(smooth)
        out += [smooth[i, : ti.size] for i, (ti, _) in enumerate(chunk)]
    return out


def _size(series: list[tuple[np.ndarray, np.ndarray]]) -> int:
    """The longest series' length rounded up to a multiple of 256 (the padded time axis)."""
    return -(-max(ti.size for ti, _ in series) // 256) * 256


def jerk_intensity(series: list[tuple[np.ndarray, np.ndarray]], noise: float) -> float:
    """The smoothing's jerk intensity for ``series`` with noise std ``noise``: the smallest on
    :data:`Q_GRID` whose pooled RMS residual (smoothed minus observed) is at most ``noise``, over
    up to :data:`Q_SERIES` of the series (a seeded choice)."""
    steps = np.concatenate([np.diff(ti) for ti, _ in series])
    base = noise**2 / max(float(np.median(steps)), 1e-12) ** 5
    pick = np.random.default_rng(0).permutation(len(series))[:Q_SERIES]
    chosen = [series[i] for i in pick]
    tiled = [s for s in chosen for _ in Q_GRID]
    q = np.tile(base * 10.0**Q_GRID, len(chosen))
    smooth = _smooth(tiled, noise, q, _size(series))
    sq = np.zeros(Q_GRID.size)
    count = 0
    for j, (ti, zi) in enumerate(tiled):
        sq[j % Q_GRID.size] += np.sum((smooth[j][:, 0] - zi) ** 2)
        count += ti.size if j % Q_GRID.size == 0 else 0
    rms = np.sqrt(sq / count)
    ok = np.flatnonzero(rms <= noise)
    return float(base * 10.0 ** Q_GRID[ok[0] if ok.size else -1])


def kalman_derivatives(
    series: list[tuple[np.ndarray, np.ndarray]], noise: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """First and second time derivatives of each ``(t, z)`` in ``series`` (increasing times
    ``t`` ``(n,)`` [s], values ``z`` ``(n,)`` with noise of std ``noise``): the Kalman smoother's
    velocity and acceleration at ``t`` (see the module docstring), one ``(first, second)`` per
    series."""
    return [(x[:, 1], x[:, 2]) for x in _kalman_fit(series, noise)]


def _kalman_fit(
    series: list[tuple[np.ndarray, np.ndarray]], noise: float, like: list | None = None
) -> list[np.ndarray]:
    """The Kalman smoother's ``(value, first, second)`` at each series' times: ``(n_i, 3)`` each,
    at the jerk intensity chosen on ``like`` (default: ``series``)."""
    like = series if like is None else like
    scale = max(float(np.max([np.ptp(z) for _, z in like])), 1.0)
    noise = max(float(noise), 1e-9 * scale)  # noise-free data: smooth to (nearly) interpolation
    q = jerk_intensity(like, noise)
    return _smooth(series, noise, np.full(len(series), q), _size(like))


def spline_derivatives(
    series: list[tuple[np.ndarray, np.ndarray]], noise: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """As :func:`kalman_derivatives`, from a quintic FITPACK smoothing spline (irregular abscissae
    as they are) held to ``Σ ‖z_i − s(t_i)‖² ≤ d n σ²``; consecutive series that share their
    times array (a trajectory's x and y, as :func:`~fhnn.data.table.position_series` gives them)
    are one curve in ``d`` dimensions with common knots (:func:`scipy.interpolate.splprep`), so
    that the estimate turns with the table; a lone series is
    :class:`scipy.interpolate.UnivariateSpline`'s. Fewer than 6 samples get a lower degree."""
    return [(x[:, 1], x[:, 2]) for x in _spline_fit(series, noise)]


def _curves(series: list[tuple[np.ndarray, np.ndarray]]) -> list[tuple[np.ndarray, list[np.ndarray]]]:
    """Consecutive series that share one times array (the same object), as ``(t, [z, …])``."""
    curves: list[tuple[np.ndarray, list[np.ndarray]]] = []
    for t, z in series:
        if curves and curves[-1][0] is t:
            curves[-1][1].append(z)
        else:
            curves.append((t, [z]))
    return curves


def _spline_fit(series: list[tuple[np.ndarray, np.ndarray]], noise: float) -> list[np.ndarray]:
    """The smoothing spline's ``(value, first, second)`` at each series' times: ``(n_i, 3)`` each."""
    from scipy.interpolate import UnivariateSpline, splev, splprep  # here: importing costs 0.7 s

    out = []
    for t, zs in _curves(series):
        degree = min(SPLINE_DEGREE, t.size - 1)
        if len(zs) == 1:
            spline = UnivariateSpline(t, zs[0], k=degree, s=t.size * noise**2)
            second = spline.derivative(2)(t) if degree >= 2 else np.zeros_like(t)
            out.append(np.stack([spline(t), spline.derivative(1)(t), second], axis=1))
            continue
        tck, _ = splprep(zs, u=t, k=degree, s=len(zs) * t.size * noise**2)
        parts = [splev(t, tck, der=d) if d <= degree else [np.zeros_like(t)] * len(zs) for d in range(3)]
        out += [np.stack([parts[d][j] for d in range(3)], axis=1) for j in range(len(zs))]
    return out


#: The velocity estimators ``fhnn import --smoother`` offers, by name.
SMOOTHERS = {"spline": spline_derivatives, "kalman": kalman_derivatives}

#: Series (at most; a seeded choice) that :func:`derivative_error` smooths again.
ERROR_SERIES = 64


def derivative_error(
    series: list[tuple[np.ndarray, np.ndarray]], noise: float, smoother: str, seed: int = 0
) -> float:
    """The RMS error of ``smoother``'s first derivatives of ``series`` with noise of std ``noise``,
    by a parametric bootstrap: up to :data:`ERROR_SERIES` of the series (a seeded choice) are
    smoothed, fresh noise N(0, noise²) is added to the smoothed values, they are smoothed again
    (the Kalman smoother at the intensity it chose on all of ``series``, not on the smoother
    copies), and the RMS difference of the two first derivatives over every sample is the
    estimate (the series' first and last samples, which the smoother sees from one side,
    included). Units: the values' per second; 0 for noise-free data.

    It sees the noise's part of the error, not a smoother's bias. Measured on issue 14's tracks
    (``benchmarks/own_data.py``: 1 mm noise, 0.05 s ± 30 %; five bootstrap seeds): 1.38–1.67 mm/s
    against the spline's true RMS error of 1.53 mm/s (data seed 0), 1.60–1.77 against 1.51 (seed 1);
    on 40 sinusoids (``tests/test_import.py``) 1.04–1.13 of the spline's error and 0.50–0.74 of
    the Kalman smoother's, whose error also holds a bias."""
    if smoother not in SMOOTHERS:
        raise ConfigError(f"unknown smoother {smoother!r}; available: {', '.join(SMOOTHERS)}")
    if noise <= 0:
        return 0.0

    def fit(part: list[tuple[np.ndarray, np.ndarray]]) -> list[np.ndarray]:
        if smoother == "kalman":  # at the intensity chosen on all of series
            return _kalman_fit(part, noise, like=series)
        return _spline_fit(part, noise)

    rng = np.random.default_rng(seed)
    curves = _curves(series)  # whole curves: the spline fits a trajectory's axes together
    pick = np.sort(rng.permutation(len(curves))[: max(1, ERROR_SERIES // len(curves[0][1]))])
    chosen = [(curves[i][0], z) for i in pick for z in curves[i][1]]
    fitted = fit(chosen)
    # each pair keeps its curve's times array, so the refit groups the axes as the fit did
    again = [(t, x[:, 0] + rng.normal(0.0, noise, t.size)) for (t, _), x in zip(chosen, fitted, strict=True)]
    refitted = fit(again)
    diff = np.concatenate([b[:, 1] - a[:, 1] for a, b in zip(fitted, refitted, strict=True)])
    return float(np.sqrt(np.mean(diff**2)))


#: The default choice: :data:`AUTO_SPLINE_ROWS` decides between the estimators.
AUTO = "auto"
#: Tables of at most this many rows get the spline under :data:`AUTO`, larger ones the Kalman
#: smoother. FITPACK's time grows faster than the series' length (per series of a random walk
#: sampled at 0.05 s ± 30 %: 1.0 / 3.0 / 8.8 / 23 ms for 250 / 500 / 1,000 / 2,000 samples; of a
#: smooth track with 1 mm noise 0.5 / 2.0 / 4.8 / 8.4 ms), so 200,000 rows (two series each) take
#: at most ~5 s in it; 2 million rows took 66 s against 5.8 s for the Kalman smoother
#: (``docs/design/data/own_data.json``, before this choice was the default).
AUTO_SPLINE_ROWS = 200_000


def choose_smoother(name: str, rows: int) -> str:
    """The estimator (a key of :data:`SMOOTHERS`) that ``name`` stands for on a table of ``rows``
    rows: ``name`` itself, or for :data:`AUTO` the spline up to :data:`AUTO_SPLINE_ROWS` rows and
    the Kalman smoother above."""
    if name == AUTO:
        return "spline" if rows <= AUTO_SPLINE_ROWS else "kalman"
    if name not in SMOOTHERS:
        raise ConfigError(f"--smoother must be one of {', '.join([AUTO, *SMOOTHERS])}, got {name!r}")
    return name


def smooth_derivatives(
    series: list[tuple[np.ndarray, np.ndarray]], noise: float, smoother: str = "spline"
) -> list[tuple[np.ndarray, np.ndarray]]:
    """First and second time derivatives of every series by the estimator ``smoother`` (a key of
    :data:`SMOOTHERS`)."""
    if smoother not in SMOOTHERS:
        raise ConfigError(f"unknown smoother {smoother!r}; available: {', '.join(SMOOTHERS)}")
    return SMOOTHERS[smoother](series, noise)


__all__ = [
    "AUTO",
    "AUTO_SPLINE_ROWS",
    "SMOOTHERS",
    "choose_smoother",
    "derivative_error",
    "jerk_intensity",
    "kalman_derivatives",
    "lagrange_residuals",
    "noise_level",
    "robust_std",
    "rts_smooth",
    "smooth_derivatives",
    "spline_derivatives",
]
