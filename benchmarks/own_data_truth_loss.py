"""Does the training objective prefer the truth on issue 14's data? Its loss at the truth.

``benchmarks/own_data.py`` trains FHNN on a tracker's positions and finds the added masses, but on
most fits a quadratic drag ``c_q`` nearly flat in σ with the linear drag ``c_l`` several percent too
high (``docs/benchmarks/own_data_seeds10.json``). Either the objective prefers that split (a bias of
the loss, which no optimiser would fix) or the optimiser stops short of the truth. This script
evaluates ``fhnn train``'s own loss — the same trainer, windows and weighting — on every training
window and on the validation windows, at the trained run's model, at the simulator's true
equations (:meth:`fhnn.data.dataset.Dataset.equations` in place of the model's, flow and
coefficient laws exact), and at each with the other's flow: the learned flow with the true
coefficients, the true flow with the learned coefficients. Which of the two parts carries the gap
between the run and the truth, and whether the learned coefficients or the true ones fit better
under the learned flow (the flow the coefficients were trained with), says whether the split's
miss is the optimiser's.

``--window W`` and ``--drift free|model`` score on other windows than the run trained on
(``train.shoot=W``, ``train.shoot_drift``): where the truth's loss stands on longer windows.
``--tracks`` scores whole tracks instead, by maximum likelihood: each training and validation
track's start state fitted to its positions under the model (Gauss–Newton, as ``fhnn predict``
fits a history: :func:`fhnn.evaluation.predict.estimate_states`), the mean square of the position
residuals left [m²] per axis, and its excess over the truth's in units of the noise,
``Δχ² = 2 n Δ(mean square) / σ²`` (``n`` samples, σ the import's noise estimate): a likelihood
ratio, so a few units separate two models and thousands mean the data reject one of them.

Usage (after ``benchmarks/own_data.py --data-seed K`` has trained its run in ``--out``)::

    python benchmarks/own_data_truth_loss.py [--out benchmarks/_own_data] [--data-seeds 0,1]
        [--window W] [--drift free|model] [--tracks]
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import equinox as eqx
import numpy as np
from own_data import trained_run

from fhnn.data.dataset import Split
from fhnn.evaluation.predict import estimate_states
from fhnn.training.trainer import Trainer, data_loss, loss_terms

#: ``loss_terms`` compiled once for every model and window set the script scores.
_terms = eqx.filter_jit(loss_terms)

#: The models scored: the trained run, the true equations, and each with the other's flow.
MODELS = ("learned", "truth", "learned flow, true coefficients", "true flow, learned coefficients")


def scored_models(learned: eqx.Module, true_eom: eqx.Module) -> dict[str, eqx.Module]:
    """:data:`MODELS` from the trained run's model and the simulator's equations of motion."""
    return dict(
        zip(
            MODELS,
            (
                learned,
                eqx.tree_at(lambda m: m.eom, learned, true_eom),
                eqx.tree_at(lambda m: m.eom.coefficients, learned, true_eom.coefficients),
                eqx.tree_at(lambda m: m.eom.flow, learned, true_eom.flow),
            ),
            strict=True,
        )
    )


def track_misfit(model: eqx.Module, split: Split) -> float:
    """The mean square [m²] per axis of ``split``'s observed positions about ``model``'s
    trajectories, each track's start state fitted to them (:func:`estimate_states`)."""
    _, rms = estimate_states(model, split.times, split.states[..., :2], mask=split.mask, force=split.forces)
    counts = split.sample_counts
    return float(np.sum(rms**2 * counts) / np.sum(counts))


def track_loss(out: Path, seed: int) -> tuple[dict[str, dict[str, float]], dict[str, int], float]:
    """Per split ("train", "val"), the whole-track misfit (:func:`track_misfit`) of each of
    :data:`MODELS` on data seed ``seed`` in ``out``; the splits' sample counts and the import's
    position noise σ [m]."""
    imported, scored, run = trained_run(out, seed)
    models = scored_models(run.state.best_model, scored.equations())
    splits = {"train": imported.train, "val": imported.val}
    loss = {k: {name: track_misfit(m, sp) for name, m in models.items()} for k, sp in splits.items()}
    return loss, {k: int(sp.sample_counts.sum()) for k, sp in splits.items()}, imported.obs_noise


def truth_loss(
    out: Path, seed: int, window: int = 0, drift: str | None = None
) -> dict[str, dict[str, float]]:
    """Per split ("train": every training window, "val": the trainer's validation windows), the
    loss of each of :data:`MODELS` on data seed ``seed`` in ``out``; on windows of ``window``
    samples (0: the run's own) with ``train.shoot_drift=drift`` (``None``: the run's own)."""
    imported, scored, run = trained_run(out, seed)
    trainer = run.trainer(imported)
    if window or drift:
        cfg = trainer.config
        cfg = dataclasses.replace(cfg, shoot=window or cfg.shoot, shoot_drift=drift or cfg.shoot_drift)
        trainer = Trainer(cfg, imported.train, imported.val, window=cfg.shoot)
    models = scored_models(run.state.best_model, scored.equations())
    train = trainer.batch(trainer.train_pairs)  # every window the Adam batches are drawn from
    return {
        "train": {
            k: float(data_loss(_terms(m, train, trainer.scales), trainer.config)) for k, m in models.items()
        },
        "val": {k: float(trainer.validate(m)["total"]) for k, m in models.items()},
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("benchmarks/_own_data"))
    p.add_argument("--data-seeds", default="0,1")
    p.add_argument("--window", type=int, default=0, help="windows of this many samples (0: the run's)")
    p.add_argument("--drift", choices=("free", "model"), default=None, help="train.shoot_drift (the run's)")
    p.add_argument("--tracks", action="store_true", help="whole tracks, start states fitted")
    args = p.parse_args()
    if args.window < 0 or args.window in (1, 2):
        raise SystemExit("--window must be 0 (the run's) or at least 3 samples")
    if args.tracks and (args.window or args.drift):
        raise SystemExit("--tracks scores whole tracks: give it without --window and --drift")
    for seed in (int(s) for s in args.data_seeds.split(",")):
        if args.tracks:
            misfit, counts, noise = track_loss(args.out, seed)
            for split, values in misfit.items():
                base = values["truth"]
                print(
                    f"data seed {seed}, {'training' if split == 'train' else 'validation'} tracks "
                    f"({counts[split]} samples, noise {noise * 1e3:.3f} mm), whole-track misfit: "
                    + "; ".join(
                        f"{name} {v:.6g} m² (rms {np.sqrt(v) * 1e3:.3f} mm"
                        + (
                            ""
                            if name == "truth"
                            else f", Δχ² {2 * counts[split] * (v - base) / noise**2:+.0f}"
                        )
                        + ")"
                        for name, v in values.items()
                    )
                )
            continue
        loss = truth_loss(args.out, seed, args.window, args.drift)
        for split, values in loss.items():
            base = values["truth"]
            print(
                f"data seed {seed}, {'training' if split == 'train' else 'validation'} loss"
                + (
                    f" (windows of {args.window or 'the run'}, drift {args.drift or 'the run'})"
                    if args.window or args.drift
                    else ""
                )
                + ": "
                + "; ".join(
                    f"{name} {v:.7g}" + ("" if name == "truth" else f" ({(v - base) / base:+.2e})")
                    for name, v in values.items()
                )
            )


if __name__ == "__main__":
    main()
