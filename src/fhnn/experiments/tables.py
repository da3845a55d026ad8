"""Tables T1–T6 of docs/spec.md §6 from the model jobs' results: mean ± std over seeds, the paper beside.

Every cell is one :class:`Cell` — a (table, data set, model, horizon, metric) with our mean and
sample standard deviation over seeds in docs/spec.md §5's averaging (checkpoints ``t = 1, …, H``) and in
the paper's (``t = 0, …, H``), how many rollouts diverged, and the paper's own number where it
has one. No rollout and no seed is ever left out (:data:`DIVERGENCE_RULE`): a diverged rollout
has an infinite error, so a seed with one has an infinite error metric; a cell whose seeds are all
finite holds their mean ± std, any other cell the median over all its seeds (finite while fewer
than half of them diverged, else shown as "diverged") and the number of diverged rollouts.

Written as ``tables.json`` and ``tables.csv`` (one row per cell) and as Markdown (one table per
T and data set: a row per model and horizon, per metric the columns "ours", "ours, t=0..H" and
"paper").
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from fhnn.evaluation.metrics import METRICS
from fhnn.experiments.grid import ABLATIONS, ModelJob
from fhnn.experiments.paper import paper_value
from fhnn.models.registry import MODELS

#: (key, caption, metrics, horizons) of the trajectory tables.
TRAJECTORY_TABLES: tuple[tuple[str, str, tuple[str, ...], tuple[int, ...]], ...] = (
    ("T1", "FHNN vs Neural ODE", ("rmse_pos", "rmse_vel", "fde"), (1, 2, 3, 4, 8, 16)),
    ("T2", "FHNN vs HNN, LNN, DHN (and the baselines beyond the paper)", ("rmse_pos", "ade", "fde"), (1, 5)),
    ("T3", "FHNN at long horizons", ("rmse_pos", "rmse_vel", "fde", "outside_training"), (30, 60, 120)),
    ("T4", "FHNN across the five scenarios, 5 s", ("rmse_pos", "rmse_vel", "ade", "fde"), (5,)),
    ("T5", "FHNN ablations, 5 s", ("rmse_pos", "rmse_vel", "ade", "fde"), (5,)),
)
CAPTIONS = {key: caption for key, caption, _, _ in TRAJECTORY_TABLES}
CAPTIONS["T6"] = (
    "FHNN parameter and flow recovery: max relative error over the data's (r, σ) range; flow: "
    "relative L2 error of the velocity on a grid over the fluid within 0.25 m of a training position "
    "(not inside the obstacle's cylinder), over the data's time window for a time-dependent flow. "
    "Without actuation (solid_body_vortex, *_noact) only c / (M + m_a) is identifiable"
)
RECOVERY_METRICS = ("m_ax", "m_ay", "c_q", "c_l", "flow")
#: Column labels of the recovery metrics (the rollout metrics' come from their registry).
RECOVERY_LABELS = {"m_ax": "m_ax", "m_ay": "m_ay", "c_q": "c_q(σ)", "c_l": "c_l", "flow": "flow (rel. L2)"}


def metric_label(name: str) -> str:
    """The column label of metric ``name``: a registered rollout metric's, or a recovery metric's."""
    return METRICS[name].label if name in METRICS else RECOVERY_LABELS[name]


def is_error_metric(name: str) -> bool:
    """Whether a diverged rollout makes metric ``name`` infinite (the fractions count it as a failure)."""
    return name in METRICS and METRICS[name].error


#: How a table treats diverged rollouts; printed under every table.
DIVERGENCE_RULE = (
    "No rollout or seed is left out: a diverged rollout counts as an infinite error, so a seed with "
    "one has an infinite error; a cell with such a seed shows the median over all seeds, marked "
    "'median' ('diverged' once half the seeds or more have one), and '(k/n div.)': k of the n "
    "rollouts diverged."
)
#: Table label of every model kind and FHNN variant (from the registry).
MODEL_NAMES = MODELS.labels()


@dataclass(frozen=True)
class Cell:
    table: str
    data: str
    model: str
    horizon: int | None
    metric: str
    mean: float
    std: float
    seeds: int
    diverged: int
    rollouts: int
    mean_paper_avg: float
    std_paper_avg: float
    paper: float | None
    statistic: str = "mean"

    def text(self, paper_avg: bool = False) -> str:
        """``mean ± std`` or ``median`` (3 significant digits), "diverged", and the divergence count
        (:data:`DIVERGENCE_RULE`)."""
        mean, std = (self.mean_paper_avg, self.std_paper_avg) if paper_avg else (self.mean, self.std)
        if not math.isfinite(mean):
            return f"diverged ({self.diverged}/{self.rollouts})" if self.diverged else "n/a"
        if self.statistic == "median":
            return f"median {mean:.2e} ({self.diverged}/{self.rollouts} div.)"
        pct = self.metric in RECOVERY_METRICS or (self.metric in METRICS and METRICS[self.metric].fraction)
        if pct:
            out = f"{100 * mean:.3g} %" + (f" ± {100 * std:.2g} %" if self.seeds > 1 else "")
        else:
            out = f"{mean:.2e}" + (f" ± {std:.2e}" if self.seeds > 1 else "")
        if self.diverged and self.horizon is None:  # recovery: seeds whose value is not finite
            out += f" ({self.diverged}/{self.rollouts} seeds non-finite, left out)"
        elif self.diverged:
            out += f" ({self.diverged}/{self.rollouts} div.)"
        return out


def seed_stats(values: list[float]) -> tuple[float, float]:
    """Mean and sample std (0 for one value) of per-seed ``values`` when all are finite; else the
    median over all of them (a non-finite value counts as +inf, so the median is inf once half or
    more are) and NaN for the spread (:data:`DIVERGENCE_RULE`)."""
    v = np.array([math.inf if x is None or not math.isfinite(x) else x for x in values], dtype=float)
    if v.size == 0:
        return math.nan, math.nan
    if not np.all(np.isfinite(v)):
        return float(np.median(v)), math.nan
    return float(np.mean(v)), float(np.std(v, ddof=1)) if v.size > 1 else 0.0


def seed_value(metrics: dict, metric: str) -> float:
    """A seed's ``metric``: infinite for an error metric when one of its rollouts diverged."""
    if is_error_metric(metric) and int(metrics["diverged"]) > 0:
        return math.inf
    return float(metrics[metric])


def _cell(table: str, data: str, model: str, horizon: int | None, metric: str, results: list[dict]) -> Cell:
    if horizon is None:  # recovery: the seeds' finite values, the others counted
        every = [_recovery_value(r, metric) for r in results]
        values = [v for v in every if math.isfinite(v)]
        mean, std = seed_stats(values)
        computed = [r for r in results if r.get("recovery") is not None]
        left_out = sum(
            1 for r, v in zip(results, every, strict=True) if r.get("recovery") and not math.isfinite(v)
        )
        return Cell(
            table,
            data,
            model,
            None,
            metric,
            mean,
            std,
            len(values),
            left_out,
            len(computed),
            math.nan,
            math.nan,
            None,
        )
    h = str(horizon)
    spec = [r["spec_metrics"][h] for r in results]
    paper = [r["paper_metrics"][h] for r in results]
    values = [seed_value(m, metric) for m in spec]
    mean, std = seed_stats(values)
    mean_p, std_p = seed_stats([seed_value(m, metric) for m in paper])
    statistic = "mean" if all(math.isfinite(v) for v in values) else "median"
    if metric == "outside_training":
        mean_p, std_p = math.nan, math.nan
    return Cell(
        table,
        data,
        model,
        horizon,
        metric,
        mean,
        std,
        len(results),
        sum(int(m["diverged"]) for m in spec),
        sum(int(m["n_traj"]) for m in spec),
        mean_p,
        std_p,
        paper_value(table, data if table == "T4" else model, horizon, metric),
        statistic,
    )


def _recovery_value(result: dict, metric: str) -> float:
    rec = result.get("recovery")
    if rec is None:
        return math.nan
    if metric == "flow":
        return float(rec["flow"]["rel_l2"])
    return float(rec["coefficients"][metric]["max_rel"])


def build_tables(
    jobs: list[ModelJob], results: dict[str, dict], main: tuple[str, ...], scenario_table: tuple[str, ...]
) -> list[Cell]:
    """Every cell of T1–T6 from the finished ``results`` (by job id) of ``jobs``; ``main``: the
    data sets of T1/T2/T3/T5, ``scenario_table``: those of T4."""
    groups: dict[tuple[str, str], list[dict]] = {}
    for job in jobs:
        if job.id in results:
            groups.setdefault((job.data.label, job.variant), []).append(results[job.id])
    variants = list(dict.fromkeys(job.variant for job in jobs))
    cells: list[Cell] = []

    def add(table: str, data: str, model: str, metrics: tuple[str, ...], horizons: tuple[Any, ...]) -> None:
        rs = groups.get((data, model))
        if rs:
            cells.extend(_cell(table, data, model, h, m, rs) for h in horizons for m in metrics)

    for key, _, metrics, horizons in TRAJECTORY_TABLES:
        if key == "T4":
            for data in scenario_table:
                add(key, data, "fhnn", metrics, horizons)
            continue
        for data in main:
            models = {
                "T1": ("fhnn", "node"),
                "T2": tuple(v for v in variants if v in MODELS and v != "node"),
                "T3": ("fhnn",),
                "T5": ("fhnn", *(v for v in variants if v in ABLATIONS)),
            }[key]
            for model in models:
                add(key, data, model, metrics, horizons)
    for data in dict.fromkeys(j.data.label for j in jobs if j.variant == "fhnn"):
        add("T6", data, "fhnn", RECOVERY_METRICS, (None,))
    return cells


def to_json(cells: list[Cell], provenance: dict[str, Any] | None = None) -> str:
    """``{"provenance": …, "cells": [one object per cell]}``; NaN becomes null."""
    rows = [
        {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in asdict(c).items()}
        for c in cells
    ]
    return json.dumps({"provenance": provenance, "cells": rows}, indent=1)


def to_csv(cells: list[Cell]) -> str:
    buffer = io.StringIO()
    names = list(asdict(cells[0]).keys()) if cells else list(Cell.__dataclass_fields__)
    writer = csv.DictWriter(buffer, fieldnames=names, lineterminator="\n")
    writer.writeheader()
    for c in cells:
        writer.writerow({k: ("" if v is None else v) for k, v in asdict(c).items()})
    return buffer.getvalue()


def layout(cells: list[Cell]) -> list[tuple[str, str, list[str], list[list[str]]]]:
    """The tables as ``(key, title, header, rows)`` of strings, one per T and data set."""
    out = []
    for key in dict.fromkeys(c.table for c in cells):
        tcells = [c for c in cells if c.table == key]
        datas = ["all"] if key in ("T4", "T6") else list(dict.fromkeys(c.data for c in tcells))
        for data in datas:
            sub = tcells if data == "all" else [c for c in tcells if c.data == data]
            metrics = list(dict.fromkeys(c.metric for c in sub))
            first = "data set" if key in ("T4", "T6") else "model"
            header = [first] if key == "T6" else [first, "H [s]"]
            for m in metrics:
                if key == "T6":
                    header.append(metric_label(m))
                elif m == "outside_training":
                    header.append(metric_label(m))
                else:
                    header += [metric_label(m), "ours, t=0..H", "paper"]
            rows = []
            keys = list(dict.fromkeys((c.data if key in ("T4", "T6") else c.model, c.horizon) for c in sub))
            for name, h in keys:
                row = [name if key in ("T4", "T6") else MODEL_NAMES.get(name, name)]
                if key != "T6":
                    row.append(f"{h:g}")
                for m in metrics:
                    match = [
                        c
                        for c in sub
                        if c.metric == m
                        and c.horizon == h
                        and (c.data if key in ("T4", "T6") else c.model) == name
                    ]
                    if not match:
                        row += ["–"] if key == "T6" or m == "outside_training" else ["–", "–", "–"]
                        continue
                    c = match[0]
                    if key == "T6" or m == "outside_training":
                        row.append(c.text())
                    else:
                        row += [
                            c.text(),
                            c.text(paper_avg=True),
                            "–" if c.paper is None else f"{c.paper:.2e}",
                        ]
                rows.append(row)
            title = f"{key}: {CAPTIONS[key]}" + ("" if data == "all" else f" — {data}")
            out.append((key, title, header, rows))
    return out


def to_markdown(cells: list[Cell], seeds: int) -> str:
    """All tables as Markdown sections."""
    parts = []
    for key, title, header, rows in layout(cells):
        parts.append(f"### {title}\n")
        parts.append("| " + " | ".join(header) + " |")
        parts.append("|" + "|".join([" --- "] + [" ---: "] * (len(header) - 1)) + "|")
        parts.extend("| " + " | ".join(r) + " |" for r in rows)
        parts.append("")
        if key in CAPTIONS and key != "T6":
            parts += [f"*{DIVERGENCE_RULE}*", ""]
    return cell_note(seeds) + "\n\n" + "\n".join(parts)


def cell_note(seeds: int) -> str:
    """What a table cell holds, for the reader of a report."""
    return (
        f"Each cell: mean ± sample std over {seeds} seed(s) (docs/spec.md §5 averaging, t = 1..H); "
        "'ours, t=0..H' averages the paper's way; 'paper' is the paper's number on its own data. "
        + DIVERGENCE_RULE
    )
