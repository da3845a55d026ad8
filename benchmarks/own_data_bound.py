"""How precisely issue 14's data can fix the coefficients at all: the Cramér–Rao bound.

``benchmarks/own_data.py`` trains on a tracker's positions (1 mm noise, times jittered ±30 % around
0.05 s, 5 % of rows dropped) and scores the coefficients against the truth. This script asks what
*any* unbiased estimator could do with the same observations. It takes the simulator's own
equations (:meth:`fhnn.data.dataset.Dataset.equations`: the Lamb–Oseen flow and the coefficient
laws) with a few parameters free, every training trajectory's start state free too (a nuisance
for each, as a forecaster's fitted start), and the observed positions of the imported training
split with independent N(0, σ_n²) errors; the Fisher information of the parameters is
``Σ Jᵀ J / σ_n²`` (``J``: the positions' sensitivities, forward-mode through an RK4 solve at the
simulation's 0.01 s), the start states are eliminated (Schur complement), and its inverse bounds
the covariance of any unbiased estimate. Derived quantities (``c_q(σ)`` at the visited σ, the
total drag, the ratios ``c / (M + m_a)``) by the delta method.

Three families, each with the flow's ``Γ`` and ``r_c`` free and each parameter relative to its
true value:

- ``law``: the truth's own form — ``m_ax, m_ay, c_l`` constants, ``c_q = c_inf + c_0 / (1 + σ/σ_ref)``
  (8 parameters). Knowing the form of the law is more than FHNN knows, so this is a floor;
- ``knots``: ``c_q(σ)`` free at ``--knots`` values of σ, linear between them and held beyond
  (spread over the visited σ by quantile, or evenly in log σ with ``--log-knots``: as free at the
  slowest speeds, where the data are few, as at the fastest): closer to what a coefficient net
  must pin down;
- ``all-knots``: the added masses free at the same values of σ too (FHNN's masses are functions of
  ``(r, σ)``, as are its ``c_q``).

FHNN's nets (flow and coefficients as functions) have more freedom than either, so the bound of an
unbiased estimator with FHNN's freedom would be larger still; FHNN's estimates are not unbiased
(smooth nets, a finite training), so for them the bound is a reference scale, not a floor their
errors cannot go below. ``--flow-bumps K`` frees the flow besides ``Γ`` and ``r_c``: ``K × K`` Gaussian
stream-function bumps over the training positions' box, each as wide as their spacing
(:class:`BumpedFlow`), a learned flow's large-scale freedom; bumps no track comes near are left out
as not identifiable. The bound says whether a target can be met with these data at all: a 90 %
interval of an unbiased estimate is at least ``2 · 1.645 · sd`` wide.

``--window W`` cuts every track into windows of ``W`` observed samples (each observation in one),
each solved from a start state of its own, as ``fhnn train``'s multi-step loss sees the data
(windows of 40 samples on estimated velocities): the information such windows hold. With
``--start-prior`` each window's start is known besides to the import's position noise and
velocity error (:func:`fhnn.data.observation.start_errors`, what the loss's weighting assumes). The
loss's windows overlap and its nets are smooth, so for it these numbers are a guide, not a strict
bound.

Usage::

    python benchmarks/own_data_bound.py [--out DIR] [--data-seed K] [--no-forcing] [--noise STD]
        [--knots K] [--log-knots] [--flow-bumps K] [--window W [--start-prior]]

``--out`` is ``own_data.py``'s folder (default ``benchmarks/_own_data``): its data are reused
(simulated and imported as ``own_data.py`` does where they are not there).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from own_data import data_suffix, make_data, with_truth

from fhnn.data.dataset import read_dataset
from fhnn.data.observation import start_errors
from fhnn.evaluation.recovery import SIGMA_BANDS, drag_terms, flow_box, visited_r_sigma
from fhnn.physics.actuation import actuation_force
from fhnn.physics.body import AbstractLaw, CoefficientLaws, Constant
from fhnn.physics.flows import AbstractFlow
from fhnn.physics.integrators import rk4_solve

LEVEL_Z = 1.6448536269514722  # the normal's 95 % quantile: a 90 % interval is ±z·sd


class BumpedFlow(AbstractFlow):
    """``base`` plus Gaussian stream-function bumps ``Σ_k a_k exp(−|x − c_k|² / 2w²)`` [m²/s]:
    large-scale flow freedom beside the base flow's own parameters."""

    base: AbstractFlow
    centres: jax.Array  # (K, 2) [m]
    width: float  # [m]
    amplitudes: jax.Array  # (K,) [m²/s]

    def bumps(self, xy):
        d2 = jnp.sum((jnp.asarray(xy) - self.centres) ** 2, axis=1)
        return jnp.dot(self.amplitudes, jnp.exp(-0.5 * d2 / self.width**2))

    def stream(self, xy, t):
        return self.base.stream(xy, t) + self.bumps(xy)

    def velocity(self, xy, t):
        g = jax.grad(self.bumps)(jnp.asarray(xy, float))
        return self.base.velocity(xy, t) + jnp.stack([g[1], -g[0]])


class KnotLaw(AbstractLaw):
    """A coefficient linear in σ between ``values`` at ``knots`` [m/s], held beyond them."""

    knots: jax.Array
    values: jax.Array

    def __call__(self, r, sigma):
        return jnp.interp(sigma, self.knots, self.values)


#: The families of :func:`parametrised`: which coefficients are free functions of σ (at the knots).
FAMILIES = {"law": (), "knots": ("c_q",), "all-knots": ("m_ax", "m_ay", "c_q")}


def parametrised(truth, family: str, knots: np.ndarray, bumps: tuple[np.ndarray, float] | None = None):
    """``(build, names)``: ``build(θ)`` the equations with each free parameter at ``base · (1 + θ_i)``,
    ``names`` their names. The base is the truth: its constants and its ``c_q`` law's three
    parameters, or for a coefficient free at the knots (:data:`FAMILIES`) its true law sampled there.
    ``bumps = (centres (K, 2) [m], width [m])``: the flow free besides in K Gaussian stream-function
    bumps (:class:`BumpedFlow`), their amplitudes ``θ · Γ/2π`` (zero in the truth) last in ``θ``."""
    co, flow = truth.coefficients, truth.flow
    sig = jnp.asarray(knots)
    free = FAMILIES[family]
    parts: list[tuple[str, jax.Array]] = []  # (name, base values)
    for name in ("m_ax", "m_ay"):
        law = getattr(co, name)
        parts.append((name, law(jnp.zeros_like(sig), sig) if name in free else jnp.array([law.value])))
    parts += [("c_l", jnp.array([co.c_l.value])), ("gamma", jnp.array([flow.gamma]))]
    parts.append(("r_c", jnp.array([flow.core_radius])))
    law = co.c_q
    cq_base = (
        law(jnp.zeros_like(sig), sig) if "c_q" in free else jnp.array([law.c_inf, law.c_0, law.sigma_ref])
    )
    parts.append(("c_q", cq_base))
    sizes = [len(b) for _, b in parts]
    base = jnp.concatenate([b for _, b in parts])
    n_base = int(base.size)
    names = []
    for name, b in parts:
        if len(b) == 1:
            names.append(name)
        elif name == "c_q" and "c_q" not in free:
            names += ["c_inf", "c_0", "sigma_ref"]
        else:
            names += [f"{name}({k:.3g})" for k in knots]

    if bumps is not None:
        names += [f"bump{k}" for k in range(len(bumps[0]))]

    def build(theta):
        values = dict(
            zip(
                [n for n, _ in parts],
                jnp.split(base * (1.0 + theta[:n_base]), np.cumsum(sizes)[:-1]),
                strict=True,
            )
        )

        def law_of(name):
            v = values[name]
            if name in free:
                return KnotLaw(sig, v)
            if name == "c_q":
                return type(co.c_q)(c_inf=v[0], c_0=v[1], sigma_ref=v[2])
            return Constant(v[0])

        coefficients = CoefficientLaws(
            m_ax=law_of("m_ax"), m_ay=law_of("m_ay"), c_q=law_of("c_q"), c_l=Constant(values["c_l"][0])
        )
        eom = eqx.tree_at(
            lambda e: (e.flow.gamma, e.flow.core_radius), truth, (values["gamma"][0], values["r_c"][0])
        )
        if bumps is not None:
            amplitudes = theta[n_base:] * flow.gamma / (2.0 * np.pi)
            flow_b = BumpedFlow(eom.flow, jnp.asarray(bumps[0]), float(bumps[1]), amplitudes)
            eom = eqx.tree_at(lambda e: e.flow, eom, flow_b)
        return eqx.tree_at(lambda e: e.coefficients, eom, coefficients)

    return build, names


def fisher(
    build,
    n_par: int,
    starts: np.ndarray,
    actuation: np.ndarray,
    ts: np.ndarray,
    rows: list,
    prior: np.ndarray | None = None,
):
    """The Fisher information ``(n_par, n_par)`` of the free parameters for unit noise, each
    piece's start state eliminated; a piece ``i`` starts at ``starts[i]`` (its true state at
    ``ts[i, 0]``), is solved over the grid ``ts[i]`` ``(T,)`` (rows of one shape: padded with later
    times) under the forcing ``actuation[i]``, and ``rows[i]`` are the grid indices at which its
    position was observed. ``prior`` ``(4,)``: the information on each start state besides its
    observations, in units of the noise's (``σ_n² / var`` of the start's position and velocity;
    ``None``: none, the start is free)."""

    def positions(z, p, times):
        eom = build(z[:n_par])
        return rk4_solve(lambda s, t: eom(s, t, actuation_force(p, t)), z[n_par:], times)[:, :2]

    jac = jax.jit(jax.vmap(jax.jacfwd(positions), in_axes=(0, 0, 0)))
    z0 = np.concatenate([np.zeros((len(starts), n_par)), starts], axis=1)
    extra = np.zeros((4, 4)) if prior is None else np.diag(prior)
    total = np.zeros((n_par, n_par))
    for lo in range(0, len(starts), 16):
        part = slice(lo, lo + 16)
        sens = np.asarray(jac(jnp.asarray(z0[part]), jnp.asarray(actuation[part]), jnp.asarray(ts[part])))
        for i, j in enumerate(sens):
            obs = j[rows[lo + i]].reshape(-1, n_par + 4)  # (2·observed, parameters + start)
            info = obs.T @ obs
            a, b, c = info[:n_par, :n_par], info[:n_par, n_par:], info[n_par:, n_par:] + extra
            total += a - b @ np.linalg.solve(c, b.T)
    return total


def pieces(
    states: np.ndarray, actuation: np.ndarray, ts: np.ndarray, rows: list, window: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """The arguments ``(starts, actuation, ts, rows)`` of :func:`fisher` for the trajectories whose
    true states are ``states`` ``(N, T, 4)`` on the grid ``ts`` ``(T,)``, observed at the grid
    indices ``rows[i]``: whole (``window`` 0, each solved from the grid's start), or cut into
    windows of ``window`` observed samples, each observation in one window (a last one under 3
    samples dropped), each solved from its first observation's true state as a training window of
    the multi-step loss is."""
    if not window:
        return states[:, 0], actuation, np.broadcast_to(ts, (len(states), ts.size)), rows
    cut = [(i, r[k : k + window]) for i, r in enumerate(rows) for k in range(0, len(r), window)]
    cut = [(i, r) for i, r in cut if len(r) >= 3]
    span = max(int(r[-1] - r[0]) for _, r in cut) + 1
    dt = ts[1] - ts[0]
    return (
        np.stack([states[i, r[0]] for i, r in cut]),
        np.stack([actuation[i] for i, _ in cut]),
        np.stack([ts[r[0]] + dt * np.arange(span) for _, r in cut]),
        [r - r[0] for _, r in cut],
    )


def bound(info: np.ndarray, rcond: float = 1e-10) -> tuple[np.ndarray, int]:
    """The pseudo-inverse of ``info`` and how many directions it leaves out (not identifiable:
    eigenvalues below ``rcond`` of the largest)."""
    w, v = np.linalg.eigh(info)
    keep = w > rcond * w.max()
    return (v[:, keep] / w[keep]) @ v[:, keep].T, int((~keep).sum())


def derived(build, names, cov, points, body) -> dict:
    """Relative standard deviations: per parameter, and per visited point ``(r, σ)`` of each
    coefficient, the total drag and the ratios ``c_l/(M+m_ax)`` etc. (delta method, forward-mode)."""
    n = len(names)

    def quantities(theta):
        coef = jax.vmap(build(theta).coefficients)(points[:, 0], points[:, 1])  # (P, 4)
        _, drag = drag_terms(coef, points[:, 1], body)
        m = body["M"] + coef[:, :2]
        return jnp.log(
            jnp.stack(
                [
                    coef[:, 0],
                    coef[:, 1],
                    coef[:, 2],
                    coef[:, 3],
                    drag,
                    coef[:, 3] / m[:, 0],
                    coef[:, 3] / m[:, 1],
                    coef[:, 2] / m[:, 0],
                    coef[:, 2] / m[:, 1],
                    drag / m[:, 0],
                    drag / m[:, 1],
                ],
                axis=1,
            )
        )

    grad = np.asarray(jax.jacfwd(quantities)(jnp.zeros(n)))  # (P, 11, n): d log q / dθ
    sd = np.sqrt(np.maximum(np.einsum("pqi,ij,pqj->pq", grad, cov, grad), 0.0))
    labels = [
        "m_ax",
        "m_ay",
        "c_q",
        "c_l",
        "drag",
        "c_l/(M+m_ax)",
        "c_l/(M+m_ay)",
        "c_q/(M+m_ax)",
        "c_q/(M+m_ay)",
    ]
    labels += ["drag/(M+m_ax)", "drag/(M+m_ay)"]
    return {"parameters": dict(zip(names, np.sqrt(np.maximum(np.diag(cov), 0.0)).tolist(), strict=True))} | {
        "per_point": dict(zip(labels, sd.T, strict=True))
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("benchmarks/_own_data"))
    p.add_argument("--data-seed", type=int, default=0)
    p.add_argument("--no-forcing", action="store_true")
    p.add_argument("--noise", type=float, default=1e-3, help="std of the position noise [m]")
    p.add_argument("--knots", type=int, default=8, help="knots of the coefficients free in σ")
    p.add_argument(
        "--log-knots",
        action="store_true",
        help="knots evenly spaced in log σ over the visited range (default: at quantiles of the visited σ)",
    )
    p.add_argument(
        "--window", type=int, default=0, help="cut the tracks into windows of this many samples (0: whole)"
    )
    p.add_argument(
        "--start-prior",
        action="store_true",
        help="each window's start known to the import's position noise and velocity error",
    )
    p.add_argument(
        "--flow-bumps",
        type=int,
        default=0,
        help="the flow free besides in K×K Gaussian stream-function bumps over the training box (0: none)",
    )
    args = p.parse_args()
    if args.flow_bumps < 0:
        raise SystemExit("--flow-bumps must be 0 or more")
    if args.window < 0 or args.window in (1, 2) or (args.start_prior and not args.window):
        raise SystemExit("--window must be 0 or at least 3 samples; --start-prior needs --window")
    args.out.mkdir(parents=True, exist_ok=True)
    fine, table, _, data, _ = make_data(
        args.out, args.data_seed, no_forcing=args.no_forcing, noise=args.noise
    )
    imported = read_dataset(data)
    scored = with_truth(imported, fine)
    truth = scored.equations()
    body = scored.constants()
    # fine's trajectories in the order the table numbers them (train, val, test), and the training
    # split's observed grid indices
    splits = [fine[name] for name in ("train", "val", "test")]
    ts = splits[0].t
    if any(s.t.shape != ts.shape or not np.allclose(s.t, ts) for s in splits):
        raise SystemExit("the fine data's splits must share one time grid")
    states = np.concatenate([s.states_clean for s in splits])
    actuation = np.concatenate([s.actuation for s in splits])
    ids = [int(k) for k in imported.extra["import"]["traj_ids"]["train"]]
    seen = ~np.isnan(table["x"])
    dt = ts[1] - ts[0]
    rows = [np.rint(np.sort(table["t"][seen & (table["traj_id"] == k)]) / dt).astype(int) for k in ids]
    points = visited_r_sigma(truth, scored)
    edges = np.quantile(points[:, 1], SIGMA_BANDS)
    band = np.clip(np.searchsorted(edges, points[:, 1], side="right") - 1, 0, len(edges) - 2)
    quad, drag = (
        np.asarray(x)
        for x in drag_terms(np.asarray(jax.vmap(truth.coefficients)(*points.T)), points[:, 1], body)
    )
    share = quad / drag
    knots = np.quantile(points[:, 1], np.linspace(0.0, 1.0, args.knots))
    if args.log_knots:  # as much freedom per decade of σ at the slowest speeds as at the fastest
        knots = np.geomspace(knots[0], knots[-1], args.knots)
    bumps = None
    if args.flow_bumps:  # K×K centres spanning the training box, each as wide as their spacing
        bx, by, _ = flow_box(scored, n=args.flow_bumps)
        gx, gy = np.meshgrid(bx, by)
        spacing = max(bx[1] - bx[0], by[1] - by[0]) if args.flow_bumps > 1 else float(np.ptp(bx))
        bumps = (np.column_stack([gx.ravel(), gy.ravel()]), float(spacing))
    starts, forcing, grids, observed = pieces(states[ids], actuation[ids], ts, rows, args.window)
    prior = None
    if args.start_prior:  # the start's errors as fhnn train's multi-step loss weighs them
        sx, sv = start_errors(imported)
        prior = (args.noise / np.array([sx, sx, sv, sv])) ** 2
    out: dict = {
        "data_seed": args.data_seed,
        "window": args.window,
        "start_prior": None if prior is None else prior.tolist(),
        "forcing": not args.no_forcing,
        "noise": args.noise,
        "flow_bumps": args.flow_bumps,
        "trajectories": len(ids),
        "observations": int(sum(len(r) for r in rows)),
        "families": {},
    }
    print(
        f"own data, data seed {args.data_seed}, {'with' if not args.no_forcing else 'without'} forcing, "
        f"noise {args.noise * 1e3:g} mm: {len(ids)} training trajectories, {out['observations']} positions"
        + (
            f"; cut into {len(starts)} windows of {args.window} samples, each from its own start state"
            + (f" (known to ±{sx * 1e3:.3g} mm, ±{sv * 1e3:.3g} mm/s)" if prior is not None else " (free)")
            if args.window
            else ""
        )
    )
    for family in FAMILIES:
        build, names = parametrised(truth, family, knots, bumps)
        info = fisher(build, len(names), starts, forcing, grids, observed, prior) / args.noise**2
        cov, dropped = bound(info)
        # the masses are not determined where a direction is lost (without forcing); with bumps, those
        # far from every track are lost too, so there it is the forcing that says
        masses_lost = args.no_forcing if bumps is not None else bool(dropped)
        d = derived(build, names, cov, jnp.asarray(points), body)
        pp = d["per_point"]
        cq, dg = ("c_q", "drag") if not masses_lost else ("c_q/(M+m_ax)", "drag/(M+m_ax)")
        res = {
            "parameters_sd": d["parameters"],
            "not_identifiable_directions": dropped,
            "mean_sd": {
                k: float(np.mean(v)) for k, v in pp.items() if k != "c_q" and (not masses_lost or "/" in k)
            },
            # without forcing the masses are not identifiable: c_q and the drag over M + m_ax instead
            "by_sigma_quantities": [cq, dg],
            "c_q_by_sigma": [
                {
                    "sigma": [float(edges[b]), float(edges[b + 1])],
                    "quadratic_share": float(share[band == b].mean()),
                    "c_q_sd_max": float(pp[cq][band == b].max()),
                    "drag_sd_max": float(pp[dg][band == b].max()),
                }
                for b in range(len(edges) - 1)
                if (band == b).any()
            ],
        }
        out["families"][family] = res
        sd = {**res["parameters_sd"], **res["mean_sd"]}
        print(
            f"\n{family}: {len(names)} parameters ({', '.join(n for n in names if not n.startswith('bump'))}"
            + (f" and {len(bumps[0])} bumps" if bumps else "")
            + "), "
            f"{dropped} direction(s) not identifiable"
            + (f"; the flow free besides in {args.flow_bumps}×{args.flow_bumps} bumps" if bumps else "")
        )
        alone = "" if masses_lost else f"m_ax {sd['m_ax']:.3%}, m_ay {sd['m_ay']:.3%}, c_l {sd['c_l']:.3%}, "
        print(
            "  relative sd (1σ; of a function of σ: its mean over the visited points): "
            f"{alone}Γ {sd['gamma']:.3%}, r_c {sd['r_c']:.3%}; "
            + ", ".join(f"{k} {v:.3%}" for k, v in res["mean_sd"].items() if "/" in k or k == "drag")
        )
        print(f"  per σ band (quadratic share; largest sd of {cq}, 90 % interval at least; of {dg}):")
        for b in res["c_q_by_sigma"]:
            print(
                f"    {b['sigma'][0]:.3f}–{b['sigma'][1]:.3f} m/s ({b['quadratic_share']:4.0%}): "
                f"{b['c_q_sd_max']:.2%} (±{LEVEL_Z * b['c_q_sd_max']:.1%}); {b['drag_sd_max']:.3%}"
            )
    cut = (f"_window{args.window}" if args.window else "") + ("_prior" if prior is not None else "")
    cut += f"_bumps{args.flow_bumps}" if args.flow_bumps else ""
    cut += f"_logknots{args.knots}" if args.log_knots else ""
    path = args.out / f"bound_seed{args.data_seed}{data_suffix(args.no_forcing, args.noise)}{cut}.json"
    path.write_text(json.dumps(out, indent=1))
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
