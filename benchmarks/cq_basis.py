"""The drag split under a stated prior on ``c_q(σ)``: FHNN with ``c_q`` in a fixed basis of σ.

FHNN's coefficient net gives ``c_q(r, σ)``; with a constant ``c_l`` the split between the two rests on
how the net behaves at the slowest relative speeds (``docs/benchmarks/drag_split.txt``,
``own_data_bound.txt``): a ``c_q`` that bends like ``1/σ`` there trades against ``c_l`` at almost no cost
in the loss. This benchmark replaces the net's ``c_q`` output by a function of σ alone in a fixed
basis, everything else (the net's masses, the constant ``c_l``, the stream net, the training plan
``fhnn train`` picks) unchanged, and scores the result against the simulator's truth:

- ``--basis chebyshev --degree N``: ``c_q = C·tanh(softplus(Σ_k a_k T_k(x))/C)``,
  ``x = 2·min(σ / (span · speed scale), 1) − 1`` (Chebyshev polynomials; no pole at σ = 0 within reach
  of a low degree, so the ``1/σ`` shape cannot be made);
- ``--basis knots``: linear between values at ``--knots`` multiples of the speed scale.

The variant is not part of the library: it is installed in this process only (the model registry's
FHNN builder is wrapped), so its runs cannot be read by ``fhnn`` commands. ``--data steady`` trains on
``steady_vortex`` (``benchmarks/fhnn_targets.py``'s data, ``--data-seed``) as ``fhnn train`` does;
``--data own`` on issue 14's positions (``benchmarks/own_data.py``'s data and ``fhnn train``
defaults). Prints the validation loss (what a plan may be chosen on) beside the recovery.

Usage::

    python benchmarks/cq_basis.py [--data steady|own] [--data-seed K] [--basis chebyshev|knots]
        [--degree N] [--span S] [--knots LIST] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from fhnn_targets import train
from own_data import make_data, run_cli, with_truth

import fhnn.models.registry as registry
from fhnn.data.dataset import read_dataset
from fhnn.evaluation.evaluate import evaluate
from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery
from fhnn.models.fhnn import CoefficientNet, build_fhnn, cap, uncap
from fhnn.runtime import default_cache_dir, use_compilation_cache
from fhnn.training.run import Run


class BasisCoefficientNet(CoefficientNet):
    """The coefficient net with ``c_q`` replaced by ``cap(basis(σ) · weights)``."""

    weights: jax.Array | None = None
    degree: int = eqx.field(static=True, default=0)  # Chebyshev degree; 0: knots
    span: float = eqx.field(static=True, default=6.0)
    knots: tuple[float, ...] = eqx.field(static=True, default=())

    def __call__(self, r, sigma):
        out = super().__call__(r, sigma)
        s = sigma / jax.lax.stop_gradient(self.sigma_scale)
        if self.degree:
            x = 2.0 * jnp.minimum(s / self.span, 1.0) - 1.0
            t = [jnp.ones_like(x), x]
            for _ in range(self.degree - 1):
                t.append(2.0 * x * t[-1] - t[-2])
            z = jnp.dot(self.weights, jnp.stack(t[: self.degree + 1]))
        else:
            z = jnp.interp(s, jnp.asarray(self.knots), self.weights)
        cq = cap(z, jnp.asarray(self.caps[2]), self.cap_map)
        return out.at[2].set(cq * jax.lax.stop_gradient(self.mask[2]))


def install(basis: str, degree: int, span: float, knots: tuple[float, ...]) -> None:
    """Make every FHNN built in this process use ``c_q`` in the basis (starting at the configured
    initial ``c_q``, constant in σ)."""

    def build(config, *, key, **args):
        model = build_fhnn(config, key=key, **args)
        co = model.eom.coefficients
        raw = float(
            uncap(np.asarray([config.init_coefficients[2]]), np.asarray([config.caps[2]]), config.cap_map)[0]
        )
        n = degree + 1 if basis == "chebyshev" else len(knots)
        weights = jnp.zeros(n).at[0].set(raw) if basis == "chebyshev" else jnp.full(n, raw)
        fields = {f: getattr(co, f) for f in CoefficientNet.__dataclass_fields__}
        new = BasisCoefficientNet(
            **fields,
            weights=weights,
            degree=degree if basis == "chebyshev" else 0,
            span=span,
            knots=knots,
        )
        return eqx.tree_at(lambda m: m.eom.coefficients, model, new)

    registry.build_fhnn = build


def steady(out: Path, seed: int | None) -> dict:
    ds, run, seconds = train("steady_vortex", out, {}, None, seed=seed)
    model = run.state.best_model
    return {
        "seconds": seconds,
        "val_loss": run.state.best_val,
        "rmse_pos_5s": evaluate(model, ds, [5])["horizons"]["5"]["rmse_pos"],
        "coefficients": coefficient_recovery(model.coefficients, ds),
        "flow_rel_l2": flow_recovery(model.flow, ds)["rel_l2"],
    }


def own(out: Path, seed: int) -> dict:
    fine, _, _, data, _ = make_data(out, seed)
    folder = out / f"run_own_seed{seed}"
    t0 = time.perf_counter()
    run_cli("train", str(data), "-o", str(folder), "-q")
    run = Run.load(folder)
    model = run.state.best_model
    scored = with_truth(read_dataset(data), fine)
    return {
        "seconds": time.perf_counter() - t0,
        "val_loss": run.state.best_val,
        "coefficients": coefficient_recovery(model.coefficients, scored),
        "flow_rel_l2": flow_recovery(model.flow, scored)["rel_l2"],
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", choices=["steady", "own"], default="steady")
    p.add_argument("--data-seed", type=int, default=0)
    p.add_argument("--basis", choices=["chebyshev", "knots"], default="chebyshev")
    p.add_argument("--degree", type=int, default=8)
    p.add_argument("--span", type=float, default=6.0, help="σ range of the Chebyshev basis [speed scales]")
    p.add_argument("--knots", default="0,0.1,0.25,0.5,1,2,4", help="knots [speed scales]")
    p.add_argument("--out", type=Path, default=Path("benchmarks/_cq_basis"))
    args = p.parse_args()
    knots = tuple(float(k) for k in args.knots.split(","))
    label = (
        f"chebyshev degree {args.degree} over {args.span:g} speed scales"
        if args.basis == "chebyshev"
        else (f"piecewise linear at {args.knots} speed scales")
    )
    folder = (
        args.out
        / f"{args.data}_seed{args.data_seed}_{args.basis}{args.degree if args.basis == 'chebyshev' else ''}"
    )
    folder.mkdir(parents=True, exist_ok=True)
    use_compilation_cache(default_cache_dir())
    install(args.basis, args.degree, args.span, knots)
    res = steady(folder, args.data_seed or None) if args.data == "steady" else own(folder, args.data_seed)
    coef = res["coefficients"]
    print(f"{args.data} data seed {args.data_seed}, c_q {label}: trained in {res['seconds']:.0f} s")
    print(
        f"  validation loss {res['val_loss']:.3e}; flow {res['flow_rel_l2']:.3%}"
        + (f"; RMSE(pos) at 5 s {res['rmse_pos_5s']:.2e} m" if "rmse_pos_5s" in res else "")
    )
    print(
        "  max rel. error: "
        + ", ".join(f"{n} {coef[n]['max_rel']:.2%}" for n in ("m_ax", "m_ay", "c_l"))
        + f"; c_q mean {coef['c_q']['mean_rel']:.2%}; total drag mean {coef['_drag']['mean_rel']:.2%}"
    )
    print(
        "  c_q max rel. error per σ band (quadratic share): "
        + ", ".join(f"{b['c_q']:.2%} ({b['quadratic_share']:.0%})" for b in coef["_by_sigma"])
    )
    (folder / "result.json").write_text(json.dumps({**vars(args), "out": str(args.out), **res}, indent=1))


if __name__ == "__main__":
    main()
