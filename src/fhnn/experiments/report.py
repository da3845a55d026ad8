"""The reproduction's report: tables, figures, ``report.md`` and a self-contained ``index.html``.

Layout of the output folder (beside ``data/`` and ``jobs/``, which the grid fills)::

    tables/T1.md … T6.md, T1.csv … , T1.json …, tables.md, tables.csv, tables.json
    figures/flow_<data>.{png,svg}              learned vs true flow (FHNN, first seed)
    figures/rollouts_<data>.{png,svg}          four test rollouts under every model (first seed)
    figures/errors_vs_horizon_<data>.{png,svg} RMSE, ADE, FDE (log scale), within-ε vs horizon
    figures/ablations_<data>.{png,svg}         RMSE(pos) at 5 s per FHNN variant
    report.md, index.html                      everything above, with configuration and timings
"""

from __future__ import annotations

import base64
import html
import json
import platform
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from fhnn.data.dataset import read_dataset
from fhnn.evaluation.metrics import METRICS
from fhnn.experiments import figures
from fhnn.experiments.grid import ABLATIONS, HORIZONS, JOB_ADAM_STEPS, ModelJob, ReproduceConfig
from fhnn.experiments.tables import (
    DIVERGENCE_RULE,
    MODEL_NAMES,
    Cell,
    build_tables,
    cell_note,
    layout,
    seed_stats,
    seed_value,
    to_csv,
    to_json,
    to_markdown,
)
from fhnn.files import write_atomic
from fhnn.runtime import __version__, provenance, source_digest
from fhnn.training.run import Run
from fhnn.training.trainer import TrainConfig

PACKAGES = ("jax", "jaxlib", "equinox", "diffrax", "optax", "numpy", "scipy", "h5py", "pysindy", "matplotlib")


def package_versions() -> dict[str, str]:
    out = {"python": platform.python_version(), "fhnn": __version__, "fhnn source": source_digest((".",))}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def write_tables(cells: list[Cell], folder: Path, seeds: int) -> list[Path]:
    """Every table as Markdown, CSV and JSON, one file per table and one with all of them."""
    folder.mkdir(exist_ok=True)
    written = []
    for key in [*dict.fromkeys(c.table for c in cells), "tables"]:
        sub = cells if key == "tables" else [c for c in cells if c.table == key]
        stamp = provenance()
        for ext, text in (
            ("md", to_markdown(sub, seeds)),
            ("csv", to_csv(sub)),
            ("json", to_json(sub, stamp)),
        ):
            path = folder / f"{key}.{ext}"
            write_atomic(path, text)
            written.append(path)
    return written


def _first_seed(jobs: list[ModelJob], data: str, variant: str) -> ModelJob | None:
    found = [j for j in jobs if j.data.label == data and j.variant == variant]
    return min(found, key=lambda j: j.seed) if found else None


def make_figures(
    out: Path, jobs: list[ModelJob], results: dict[str, dict], cells: list[Cell], config: ReproduceConfig
) -> list[Path]:
    """The figures of docs/spec.md §6 for each main scenario (PNG and SVG); the ablation bars are the T5
    cells, the error curves use the tables' statistics (mean, sample std over seeds)."""
    folder = out / "figures"
    folder.mkdir(exist_ok=True)
    written: list[Path] = []
    main = [
        j.data for j in jobs if j.data.scenario in config.main_scenarios and j.data.label == j.data.scenario
    ]
    for d in dict.fromkeys(main):
        dataset = read_dataset(out / "data" / d.filename)
        variants = list(dict.fromkeys(j.variant for j in jobs if j.data.id == d.id))
        models = [v for v in variants if v not in ABLATIONS]
        fhnn_job = _first_seed(jobs, d.label, "fhnn")
        if fhnn_job is not None:
            run = Run.load(out / "jobs" / fhnn_job.id / "run", expect_model="fhnn")
            truth = dataset.equations()
            written += figures.flow_figure(
                run.state.best_model.flow,
                truth.flow,
                dataset,
                folder / f"flow_{d.label}",
                formats=("png", "svg"),
            )
        predictions, t = {}, None
        for v in models:
            job = _first_seed(jobs, d.label, v)
            with np.load(out / "jobs" / job.id / "rollouts.npz") as npz:
                t, predictions[MODEL_NAMES.get(v, v)] = npz["t"], npz["pred"]
        if t is not None:
            k = next(iter(predictions.values())).shape[0]
            truth_states = dataset.test.states_clean[:k, : t.size]
            written += figures.rollout_figure(
                t,
                truth_states,
                predictions,
                folder / f"rollouts_{d.label}",
                title=f"{d.label}: test rollouts",
            )
        curves = {}
        for v in models:
            rs = [results[j.id] for j in jobs if j.data.id == d.id and j.variant == v]
            curves[MODEL_NAMES.get(v, v)] = {m.name: _curve(rs, m.name) for m in METRICS.values() if m.curve}
        written += figures.horizon_figure(
            list(HORIZONS),
            curves,
            folder / f"errors_vs_horizon_{d.label}",
            title=f"{d.label}: error vs horizon",
        )
        bars = [c for c in cells if c.table == "T5" and c.data == d.label and c.metric == "rmse_pos"]
        if len(bars) > 1:
            written += figures.ablation_figure(
                [MODEL_NAMES[c.model] for c in bars],
                np.array([c.mean for c in bars]),
                np.array([c.std for c in bars]),
                [c.paper for c in bars],
                folder / f"ablations_{d.label}",
                title=f"{d.label}: ablations",
            )
    return written


def _curve(results: list[dict], metric: str) -> tuple[np.ndarray, np.ndarray]:
    """Per horizon of :data:`HORIZONS`, ``metric`` over seeds as the tables state it
    (:func:`~fhnn.experiments.tables.seed_stats` of each seed's
    :func:`~fhnn.experiments.tables.seed_value`): mean and sample std, or the median and NaN."""
    stats = np.array(
        [seed_stats([seed_value(r["spec_metrics"][str(h)], metric) for r in results]) for h in HORIZONS]
    )
    return stats[:, 0], stats[:, 1]


def _timings(jobs: list[ModelJob], results: dict[str, dict]) -> dict[str, Any]:
    per_model: dict[str, list[tuple[float, float]]] = {}
    for j in jobs:
        r = results[j.id]
        per_model.setdefault(j.variant, []).append((r["train_seconds"], r["eval_seconds"]))
    return {
        "jobs": len(jobs),
        "job_seconds_total": float(sum(np.sum(v) for v in per_model.values())),
        "mean_job_seconds": {k: float(np.sum(v) / len(v)) for k, v in per_model.items()},
        # what each model got: its training time (the same budget for all) and its evaluation's
        "mean_train_seconds": {k: float(np.mean([t for t, _ in v])) for k, v in per_model.items()},
        "mean_eval_seconds": {k: float(np.mean([e for _, e in v])) for k, v in per_model.items()},
        # jobs a training guard (TrainConfig.stop_rising) or the time budget (max_time) ended before
        # their plan did: their best model is what the tables score
        "stopped_early": {
            j.label: f"step {results[j.id]['steps']}: {results[j.id]['stopped']}"
            for j in jobs
            if results[j.id].get("stopped")
        },
    }


def build_report(
    out: Path,
    config: ReproduceConfig,
    jobs: list[ModelJob],
    results: dict[str, dict],
    *,
    wall_seconds: float,
) -> Path:
    """Tables, figures, ``report.md`` and ``index.html`` in ``out``; returns the HTML's path."""
    cells = build_tables(jobs, results, config.main_scenarios, config.scenario_table)
    write_tables(cells, out / "tables", config.seeds)
    figure_paths = make_figures(out, jobs, results, cells, config)
    timings = {**_timings(jobs, results), "wall_seconds_this_run": wall_seconds, "provenance": provenance()}
    versions = package_versions()
    write_atomic(out / "timings.json", json.dumps(timings, indent=1))
    pngs = [p for p in figure_paths if p.suffix == ".png"]
    write_atomic(out / "report.md", _markdown(cells, config, versions, timings, pngs, out))
    write_atomic(out / "index.html", _html(cells, config, versions, timings, pngs))
    return out / "index.html"


def _intro(config: ReproduceConfig, timings: dict[str, Any]) -> str:
    return (
        f"fhnn {__version__}: the paper's tables (docs/spec.md §6) on our data sets, "
        f"{config.seeds} seed(s) per model"
        + (
            " (trained together, as one ensemble per cell)"
            if config.seeds_together and config.seeds > 1
            else ""
        )
        + ", "
        f"the same training for every gradient-trained model ({_plan_text(config.train)})"
        + f". {timings['jobs']} training jobs, {timings['job_seconds_total'] / 60:.1f} CPU-minutes of jobs; "
        f"this invocation took {timings['wall_seconds_this_run'] / 60:.1f} min (cached jobs are not re-run)."
        + (SMOKE_TEST if config.train.steps + config.train.lbfgs_steps < JOB_ADAM_STEPS else "")
    )


#: What the report says of a reproduction trained too briefly to compare (``fhnn reproduce --quick``).
SMOKE_TEST = (
    " **A smoke test**: training this short checks that every table and figure is made; its numbers are "
    "far from converged and are not the comparison with the paper (run without --quick for that)."
)


def _plan_text(train: TrainConfig) -> str:
    phases = [
        f"{train.warmup_steps} L-BFGS warm-up" if train.warmup_steps else "",
        f"{train.steps} Adam steps" if train.steps else "",
        f"{train.lbfgs_steps} L-BFGS polish" if train.lbfgs_steps else "",
        f"{train.track_steps} whole-track Levenberg–Marquardt" if train.track_steps else "",
    ]
    text = " + ".join(p for p in phases if p) or "no training steps"
    if train.warmup_steps and train.warmup_accept > 0:
        text += f" (the warm-up kept, and Adam skipped, at validation loss <= {train.warmup_accept:g})"
    if train.max_time > 0:
        text += f", at most {train.max_time:g} s of training per job"
    return text


def _markdown(
    cells: list[Cell],
    config: ReproduceConfig,
    versions: dict[str, str],
    timings: dict[str, Any],
    pngs: list[Path],
    out: Path,
) -> str:
    lines = ["# fhnn reproduction report", "", _intro(config, timings), "", "## Tables", ""]
    lines.append(to_markdown(cells, config.seeds))
    lines += ["## Figures", ""]
    lines += [f"![{p.stem}]({p.relative_to(out).as_posix()})" for p in pngs]
    lines += ["", "## Configuration", "", "```json", json.dumps(config.to_dict(), indent=1), "```", ""]
    lines += ["## Versions", ""] + [f"- {k}: {v}" for k, v in versions.items()]
    lines += ["", "## Mean time per job [s] (train + evaluate)", ""]
    lines += [
        f"- {MODEL_NAMES.get(k, k)}: {v:.1f} ({timings['mean_train_seconds'][k]:.1f} + "
        f"{timings['mean_eval_seconds'][k]:.1f})"
        for k, v in timings["mean_job_seconds"].items()
    ]
    lines += ["", "## Jobs stopped early (their best model is scored)", ""]
    lines += [f"- {k}: {v}" for k, v in timings["stopped_early"].items()] or ["- none"]
    return "\n".join(lines) + "\n"


_CSS = """
body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1400px;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1.5em;font-size:13px}
th,td{border:1px solid #ccc;padding:3px 7px;text-align:right}
th{background:#f0f0f0} td:first-child{text-align:left}
figure{margin:1em 0} img{max-width:100%;border:1px solid #eee}
pre{background:#f7f7f7;padding:0.6em;overflow-x:auto}
"""

# Sets data-images-loaded / data-images-total on <body> once the page has loaded, so that a
# headless browser can check that every embedded figure decoded.
_CHECK = """
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  document.body.setAttribute('data-images-total', String(imgs.length));
  document.body.setAttribute('data-images-loaded', String(ok));
});
"""


def _html(
    cells: list[Cell],
    config: ReproduceConfig,
    versions: dict[str, str],
    timings: dict[str, Any],
    pngs: list[Path],
) -> str:
    e = html.escape
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        "<title>fhnn reproduction report</title>",
        f"<style>{_CSS}</style><script>{_CHECK}</script></head><body>",
        "<h1>fhnn reproduction report</h1>",
        f"<p>{e(_intro(config, timings))}</p>",
        f"<p>{e(cell_note(config.seeds))}</p>",
        "<h2>Tables</h2>",
    ]
    for key, title, header, rows in layout(cells):
        parts.append(
            f"<h3>{e(title)}</h3><table><tr>" + "".join(f"<th>{e(h)}</th>" for h in header) + "</tr>"
        )
        parts += ["<tr>" + "".join(f"<td>{e(c)}</td>" for c in row) + "</tr>" for row in rows]
        parts.append("</table>")
        if key != "T6":
            parts.append(f"<p class='rule'>{e(DIVERGENCE_RULE)}</p>")
    parts.append("<h2>Figures</h2>")
    for p in pngs:
        data = base64.b64encode(p.read_bytes()).decode()
        parts.append(
            f"<figure><img alt='{e(p.stem)}' src='data:image/png;base64,{data}'>"
            f"<figcaption>{e(p.stem)} (SVG: figures/{e(p.stem)}.svg)</figcaption></figure>"
        )
    parts.append("<h2>Configuration</h2><pre>" + e(json.dumps(config.to_dict(), indent=1)) + "</pre>")
    parts.append("<h2>Versions</h2><table>")
    parts += [f"<tr><td>{e(k)}</td><td>{e(v)}</td></tr>" for k, v in versions.items()]
    parts.append("</table><h2>Mean time per job (train + evaluate)</h2><table>")
    parts += [
        f"<tr><td>{e(MODEL_NAMES.get(k, k))}</td><td>{v:.1f} s</td>"
        f"<td>{timings['mean_train_seconds'][k]:.1f} s + {timings['mean_eval_seconds'][k]:.1f} s</td></tr>"
        for k, v in timings["mean_job_seconds"].items()
    ]
    parts.append("</table><h2>Jobs stopped early (their best model is scored)</h2><ul>")
    parts += [f"<li>{e(k)}: {e(v)}</li>" for k, v in timings["stopped_early"].items()] or ["<li>none</li>"]
    parts.append("</ul></body></html>")
    return "\n".join(parts)
