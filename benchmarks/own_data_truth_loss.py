"""Does the training objective prefer the truth on issue 14's data? The validation loss of the truth.

``benchmarks/own_data.py`` trains FHNN on a tracker's positions and finds the added masses, but on
most fits a quadratic drag ``c_q`` nearly flat in σ with the linear drag ``c_l`` several percent too
high (``docs/benchmarks/own_data_seeds10.json``). Either the objective prefers that split (a bias of
the loss, which no optimiser would fix) or the optimiser stops short of the truth. This script
evaluates ``fhnn train``'s own validation loss — the same trainer, windows and weighting — at the
trained run's model and at the simulator's true equations (:meth:`fhnn.data.dataset.Dataset.equations`
in place of the model's, flow and coefficient laws exact), on the same imported data.

Usage (after ``benchmarks/own_data.py --data-seed K`` has trained its run in ``--out``)::

    python benchmarks/own_data_truth_loss.py [--out benchmarks/_own_data] [--data-seeds 0,1]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import equinox as eqx
from own_data import make_data, run_folder, with_truth

from fhnn.data.dataset import read_dataset
from fhnn.errors import DataFormatError
from fhnn.training.run import Run


def truth_loss(out: Path, seed: int) -> dict[str, float]:
    """The validation losses ``{"learned": …, "truth": …}`` on data seed ``seed`` in ``out``."""
    folder = run_folder(out, seed, "defaults")
    if not (folder / "run.json").exists():
        raise DataFormatError(
            f"{folder}: no trained run; run benchmarks/own_data.py --data-seed {seed} first"
        )
    fine, _, _, data, _ = make_data(out, seed)  # imported again, as own_data.py --reuse-run does
    imported = read_dataset(data)
    scored = with_truth(imported, fine)
    run = Run.load(folder)
    trainer = run.trainer(imported)
    learned = run.state.best_model
    truth = eqx.tree_at(lambda m: m.eom, learned, scored.equations())
    return {name: float(trainer.validate(m)["total"]) for name, m in (("learned", learned), ("truth", truth))}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("benchmarks/_own_data"))
    p.add_argument("--data-seeds", default="0,1")
    args = p.parse_args()
    for seed in (int(s) for s in args.data_seeds.split(",")):
        loss = truth_loss(args.out, seed)
        gap = (loss["learned"] - loss["truth"]) / loss["truth"]
        print(
            f"data seed {seed}: validation loss of the trained run {loss['learned']:.7g}, "
            f"of the true equations {loss['truth']:.7g} (the run's {gap:+.2e} relative): the objective "
            + ("prefers the truth" if gap > 0 else "prefers the trained run")
        )


if __name__ == "__main__":
    main()
