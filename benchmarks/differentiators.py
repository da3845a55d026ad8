"""fhnn's velocity estimators against PyNumDiff's on the own-data benchmark's tracker tables.

Positions of the actuated ``steady_vortex`` body sampled at irregular times (0.05 s ± 30 %, 5 % of
rows missing) with 1 mm noise (``benchmarks/own_data.py``'s recipe), 70 tracks of 20 s; each
estimator gets one track's times and noisy x and y and returns velocities at those times, scored
against the simulator's velocities (RMS over all samples, both axes; ``edge``: the first and last
0.5 s of each track, where estimators differ most). fhnn's estimators are given the noise level
its import estimates from the table (:func:`fhnn.data.derivatives.noise_level`); PyNumDiff's
parameters are chosen by its own optimiser without the truth (``pynumdiff.optimize.optimize``,
its default criterion, on the median step, once per band limit of :data:`BANDLIMITS`), then
applied with the irregular times.

    pip install -e ".[compare]"
    python benchmarks/differentiators.py [--data-seed 0] [--tracks 70] [--no-pynumdiff]
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import numpy as np
from _common import RESULTS, stamp

from fhnn.data.derivatives import kalman_derivatives, noise_level, spline_derivatives
from fhnn.data.observation import observe
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.physics.scenarios import get_scenario

OBSERVED = {"step": 0.05, "jitter": 0.3, "drop": 0.05}
EDGE = 0.5  # s
#: Signal bands [Hz] given to PyNumDiff's optimiser (it asks for one): the forcing's highest
#: frequency (0.5 Hz), half and twice it.
BANDLIMITS = (0.25, 0.5, 1.0)


def tracks(data_seed: int, n_traj: int) -> list[dict]:
    sc = get_scenario("steady_vortex")
    config = SimulationConfig.for_scenario(
        sc, n_traj=n_traj, duration=20.0, test_duration=20.0, dt=0.01, actuation="random", seed=data_seed
    )
    fine = simulate_dataset(sc, config)
    noisy = observe(fine, **OBSERVED, noise=1e-3, seed=data_seed + 1, forces=False)
    clean = observe(fine, **OBSERVED, noise=0.0, seed=data_seed + 1, velocities=True)
    out = []
    for tid in np.unique(noisy["traj_id"]):
        a, b = np.flatnonzero(noisy["traj_id"] == tid), np.flatnonzero(clean["traj_id"] == tid)
        a = a[np.isfinite(noisy["x"][a]) & np.isfinite(noisy["y"][a])]  # missing rows dropped, as import does
        b = b[np.isin(clean["t"][b], noisy["t"][a])]
        a, b = a[np.argsort(noisy["t"][a])], b[np.argsort(clean["t"][b])]  # the table's rows are shuffled
        track = {k: np.asarray(noisy[k][a], float) for k in ("t", "x", "y")}
        track |= {k: np.asarray(clean[k][b], float) for k in ("vx", "vy")}
        assert np.array_equal(track["t"], np.asarray(clean["t"][b], float))
        out.append(track)
    return out


def score(data: list[dict], velocities: list[tuple[np.ndarray, np.ndarray]]) -> dict:
    err, edge = [], []
    for tr, (vx, vy) in zip(data, velocities, strict=True):
        e = np.concatenate([vx - tr["vx"], vy - tr["vy"]])
        t = np.concatenate([tr["t"], tr["t"]])
        near = (t - t.min() < EDGE) | (t.max() - t < EDGE)
        err.append(e)
        edge.append(e[near])
    rms = lambda parts: float(np.sqrt(np.mean(np.concatenate(parts) ** 2)))  # noqa: E731
    return {"rms": rms(err), "edge_rms": rms(edge)}


def fhnn_estimator(data: list[dict], fn) -> list[tuple[np.ndarray, np.ndarray]]:
    series = [s for tr in data for s in ((tr["t"], tr["x"]), (tr["t"], tr["y"]))]
    noise = noise_level(series)
    first = [d[0] for d in fn(series, noise)]
    return [(first[2 * i], first[2 * i + 1]) for i in range(len(data))]


def dynamax_estimator(data: list[dict]) -> tuple[list[tuple[np.ndarray, np.ndarray]], dict]:
    """The Rauch–Tung–Striebel smoother of dynamax (``lgssm_smoother``) on fhnn's model: the same
    white-noise-jerk dynamics at each step's length, the same intensity and noise, the position's
    prior diffuse (10⁶ σ²) instead of set to the first sample."""
    import jax
    import jax.numpy as jnp
    from dynamax.linear_gaussian_ssm import lgssm_smoother
    from dynamax.linear_gaussian_ssm.inference import (
        ParamsLGSSM,
        ParamsLGSSMDynamics,
        ParamsLGSSMEmissions,
        ParamsLGSSMInitial,
    )

    from fhnn.data.derivatives import jerk_intensity

    series = [s for tr in data for s in ((tr["t"], tr["x"]), (tr["t"], tr["y"]))]
    noise = noise_level(series)
    q = jerk_intensity(series, noise)
    step = float(np.median(np.concatenate([np.diff(t) for t, _ in series])))
    big = 1e6 * noise**2

    @jax.jit
    def smooth(t, z):
        h = jnp.diff(t, prepend=t[:1] - step)  # weights[k]: the step into sample k (dynamax's convention)
        one, zero = jnp.ones_like(h), jnp.zeros_like(h)
        F = jnp.stack(
            [
                jnp.stack([one, h, h * h / 2], -1),
                jnp.stack([zero, one, h], -1),
                jnp.stack([zero, zero, one], -1),
            ],
            -2,
        )
        Q = q * jnp.stack(
            [
                jnp.stack([h**5 / 20, h**4 / 8, h**3 / 6], -1),
                jnp.stack([h**4 / 8, h**3 / 3, h**2 / 2], -1),
                jnp.stack([h**3 / 6, h**2 / 2, h], -1),
            ],
            -2,
        )
        params = ParamsLGSSM(
            initial=ParamsLGSSMInitial(
                mean=jnp.stack([z[0], 0.0, 0.0]), cov=jnp.diag(jnp.stack([big, big / step**2, big / step**4]))
            ),
            dynamics=ParamsLGSSMDynamics(
                weights=F, bias=jnp.zeros(3), input_weights=jnp.zeros((3, 0)), cov=Q
            ),
            emissions=ParamsLGSSMEmissions(
                weights=jnp.array([[1.0, 0.0, 0.0]]),
                bias=jnp.zeros(1),
                input_weights=jnp.zeros((1, 0)),
                cov=jnp.array([[noise**2]]),
            ),
        )
        return lgssm_smoother(params, z[:, None]).smoothed_means[:, 1]

    out = [(np.asarray(smooth(tr["t"], tr["x"])), np.asarray(smooth(tr["t"], tr["y"]))) for tr in data]
    ours = fhnn_estimator(data, kalman_derivatives)
    diff = max(
        float(np.max(np.abs(a - b)))
        for pair, mine in zip(out, ours, strict=True)
        for a, b in zip(pair, mine, strict=True)
    )
    return out, {"max_abs_difference_from_fhnn_kalman_m_per_s": diff}


def pynumdiff_estimator(
    data: list[dict], name: str, band: float
) -> tuple[list[tuple[np.ndarray, np.ndarray]], dict]:
    import pynumdiff
    from pynumdiff.optimize import optimize

    method = getattr(pynumdiff, name)
    probe = data[0]
    dt = float(np.median(np.diff(probe["t"])))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        params, _ = optimize(method, probe["x"], dt, bandlimit=band, parallel=False)
    out = []
    for tr in data:
        vx = method(tr["x"], tr["t"], **params)[1]
        vy = method(tr["y"], tr["t"], **params)[1]
        out.append((np.asarray(vx), np.asarray(vy)))
    return out, params


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data-seed", type=int, default=0)
    p.add_argument("--tracks", type=int, default=70)
    p.add_argument("--no-pynumdiff", action="store_true", help="without PyNumDiff (slow tuning)")
    args = p.parse_args()
    data = tracks(args.data_seed, args.tracks)
    rows = {}
    runs = [
        ("fhnn spline (quintic, FITPACK)", lambda: (fhnn_estimator(data, spline_derivatives), {})),
        ("fhnn Kalman/RTS (jerk model)", lambda: (fhnn_estimator(data, kalman_derivatives), {})),
        ("dynamax lgssm_smoother, fhnn's model", lambda: dynamax_estimator(data)),
    ]
    for name in () if args.no_pynumdiff else ("splinediff", "rtsdiff"):
        for band in BANDLIMITS:
            label = f"pynumdiff {name}, band {band:g} Hz"
            runs.append((label, lambda n=name, b=band: pynumdiff_estimator(data, n, b)))
    for label, run in runs:
        t0 = time.perf_counter()
        velocities, params = run()
        secs = time.perf_counter() - t0
        rows[label] = {**score(data, velocities), "seconds": secs, "params": params}
        r = rows[label]
        rms, edge = r["rms"] * 1e3, r["edge_rms"] * 1e3
        print(f"{label:34s} rms {rms:7.3f} mm/s  edges {edge:7.3f} mm/s  {secs:6.1f} s")
    record = {
        **stamp(),
        "data_seed": args.data_seed,
        "tracks": len(data),
        "samples": int(sum(tr["t"].size for tr in data)),
        "noise_m": 1e-3,
        "observed": OBSERVED,
        "estimators": rows,
    }
    (RESULTS / "differentiators.json").write_text(json.dumps(record, indent=1, default=float))
    print("wrote benchmarks/results/differentiators.json")


if __name__ == "__main__":
    main()
