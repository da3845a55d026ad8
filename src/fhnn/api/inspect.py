"""``fhnn.inspect``: the learned coefficients and flow of a run or an ensemble, as ``fhnn inspect``."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fhnn.api.fit import Fit, as_fit
from fhnn.api.report import TableData, fmt
from fhnn.data.dataset import Dataset
from fhnn.errors import ConfigError
from fhnn.evaluation.flow_summary import FlowSummary, summarise_flow
from fhnn.evaluation.recovery import (
    coefficient_recovery,
    flow_recovery,
    learned_coefficients,
    visited_r_sigma,
)
from fhnn.experiments.exports import ensemble_intervals, write_coefficients_csv, write_flow_netcdf
from fhnn.experiments.figures import coefficient_figure, flow_figure
from fhnn.experiments.laplace import identifiability_note, laplace_intervals
from fhnn.training.ensemble import LEVEL, interval


@dataclass
class Inspection:
    """What ``fhnn inspect`` found.

    Attributes:
        kind: ``"recovery"`` (simulated data: against the truth), ``"learned"`` (imported data:
            no truth) or ``"ensemble"`` (the members' median and 90 % interval).
        coefficients: per coefficient (and ratio) its numbers, as ``fhnn inspect --json`` prints.
        flow: the flow's recovery against the truth (``"recovery"`` only), else ``None``.
        sections: the report in order: lines (``str``) and tables (:class:`TableData`).
        written: the files written into the run folder.
        members: the number of runs (1 for a single run).
        forced: whether the data carry known forcing (ensembles).
        notes: what the inspection found worth saying (identifiability, a guard's stop).
        flow_summary: the learned flow in a few numbers (:func:`flow_summary`), per member.
    """

    kind: str
    coefficients: dict[str, Any]
    flow: dict[str, Any] | None
    sections: list[str | TableData]
    written: list[Path]
    members: int = 1
    forced: bool | None = None
    notes: list[str] = field(default_factory=list)
    flow_summary: list[dict[str, Any]] = field(default_factory=list)

    def json(self) -> dict[str, Any]:
        """What ``fhnn inspect --json`` prints."""
        written = [str(f) for f in self.written]
        summary = {"flow_summary": self.flow_summary}
        if self.kind == "ensemble":
            return {
                "members": self.members,
                "coefficients": self.coefficients,
                "forced": self.forced,
                **summary,
                "written": written,
            }
        if self.kind == "recovery":
            return {"coefficients": self.coefficients, "flow": self.flow, **summary, "written": written}
        return {"coefficients": self.coefficients, **summary, "written": written}

    def __str__(self) -> str:
        return "\n".join(s if isinstance(s, str) else s.text() for s in self.sections)


def inspect(
    run: Fit | str | os.PathLike[str],
    data: Dataset | str | os.PathLike[str] | None = None,
    *,
    figures: bool = True,
) -> Inspection:
    """Inspect a trained FHNN run or ensemble; writes ``coefficients.csv``, ``flow.nc`` and (with
    ``figures``) PNG figures into its folder.

    Args:
        run: a :class:`~fhnn.api.fit.Fit`, or a run or ensemble folder.
        data: the data set to inspect on (default: the one the run was trained on).
        figures: write the flow and coefficient figures.

    Returns:
        The :class:`Inspection`.

    Raises:
        ConfigError: a run that is not FHNN.
        DataFormatError: a missing or changed data set, or unreadable run files.
    """
    fit = as_fit(run, data)
    if any(r.kind != "fhnn" for r in fit.runs):
        raise ConfigError(
            f"inspect needs an fhnn run; a {fit.runs[0].kind!r} model has no flow or coefficients"
        )
    if fit.is_ensemble:
        found = _ensemble(fit, figures)
    elif fit.dataset.imported:
        found = _learned(fit, figures)
    else:
        found = _recovery(fit, figures)
    summaries = [summarise_flow(m.flow, fit.dataset) for m in fit.models]
    found.flow_summary = [f.to_dict() for f in summaries]
    found.sections.insert(len(found.sections) - 1, flow_summary(summaries))  # before "written:"
    return found


def flow_summary(summaries: list[FlowSummary]) -> str:
    """One line on the learned flow of a run, or of an ensemble's members (then each number with
    its 90 % interval over the members): a vortex's centre, circulation and core radius, or a
    flow's speed range and vorticity peak."""

    def show(values: list[float], unit: str) -> str:
        if len(values) == 1:
            return f"{fmt(values[0])} {unit}"
        mid, lo, hi = (float(a) for a in interval(np.asarray(values)))
        return f"{fmt(mid)} {unit} [{fmt(lo)}, {fmt(hi)}]"

    first = summaries[0]
    share = show([s.explained * 100 for s in summaries], "%")
    if all(s.vortex for s in summaries):
        return (
            f"flow: a vortex centred at x {show([s.centre[0] for s in summaries], 'm')}, "
            f"y {show([s.centre[1] for s in summaries], 'm')}; circulation "
            f"{show([s.circulation for s in summaries], 'm²/s')}, core radius "
            f"{show([s.core_radius for s in summaries], 'm')} (a Lamb–Oseen vortex fitted to the "
            f"learned velocity explains {share} of its variance over the data's region)"
        )
    return (
        f"flow: not one vortex (the best Lamb–Oseen fit explains {share} of the learned velocity's "
        f"variance); speeds {fmt(first.speed_range[0])} – {fmt(first.speed_range[1])} m/s over the "
        f"data's region, |vorticity| greatest at ({fmt(first.vorticity_peak[0])}, "
        f"{fmt(first.vorticity_peak[1])}) m: ω = {show([s.peak_vorticity for s in summaries], '1/s')}"
    )


def _exports(models: list[Any], dataset: Dataset, folder: Path) -> list[Path]:
    eoms = [m.eom for m in models]
    flows = [m.flow for m in models]
    one = len(models) == 1
    return [
        write_coefficients_csv(eoms[0] if one else eoms, dataset, folder / "coefficients.csv"),
        write_flow_netcdf(flows[0] if one else flows, dataset, folder / "flow.nc"),
    ]


#: The unit of each coefficient the tables show ("–": dimensionless).
COEFFICIENT_UNITS = {"m_ax": "kg", "m_ay": "kg", "c_q": "–", "c_l": "N·s/m", "drag": "N·s/m"}


#: The column of the Laplace intervals from the whole-track fit's curvature.
LAPLACE_COLUMN = "90 % interval (curvature)"


def laplace_text(laplace: dict[str, dict[str, Any]] | None, name: str) -> str:
    """A quantity's Laplace interval as a table shows it: the bounds, "not determined" or "–"
    (no curvature: a model without whole-track parameters)."""
    if laplace is None:
        return "–"
    r = laplace[name]
    if not r["determined"]:
        return "not determined"
    return f"{fmt(r['lo'])} – {fmt(r['hi'])}" + (" (weak)" if r["weak"] else "")


def with_unit(name: str) -> str:
    """A coefficient's name with its unit, as the tables show it (``"m_ax [kg]"``)."""
    unit = COEFFICIENT_UNITS.get(name)
    return f"{name} [{unit}]" if unit else name


def drag_note(sigma_min: float) -> str:
    """What data with known forcing say about c_q and c_l apart."""
    return (
        "note: c_q and c_l share the drag; the data fix their sum, the total drag coefficient "
        "drag = ½ρA c_q σ + c_l [N·s/m], more tightly than the split, which rests on how the drag "
        f"changes with σ down to the slowest relative speed in the data ({fmt(sigma_min)} m/s)"
    )


def held_masses_note(model: Any) -> str:
    """Where training held the added masses to two constants: their values are a free gauge."""
    if getattr(model.coefficients, "mass_raw", None) is None:
        return ""
    return (
        " Training held the added masses to two constants (model.added_mass=constant), since the "
        "data cannot fix them: their values are where training left that free gauge."
    )


def _learned(fit: Fit, figures: bool) -> Inspection:
    """On imported data: the learned coefficients and flow, no truth to compare."""
    model, dataset, folder = fit.models[0], fit.dataset, fit.runs[0].folder
    coef = learned_coefficients(model.eom, dataset)
    laplace = laplace_intervals(model, dataset, fit.runs[0].train_config)
    coef["_laplace"] = laplace
    written = _exports([model], dataset, folder)
    if figures:
        written += flow_figure(model.flow, None, dataset, folder / "flow")
        written += coefficient_figure(
            model.coefficients, None, dataset, folder / "coefficients", flow_of=model.eom
        )
    rows = [
        [
            with_unit(n),
            fmt(coef[n]["median"]),
            f"{fmt(coef[n]['learned_min'])} – {fmt(coef[n]['learned_max'])}",
            laplace_text(laplace, n),
        ]
        for n in ("m_ax", "m_ay", "c_q", "c_l", "drag")
    ]
    sections: list[str | TableData] = [
        TableData(
            "learned coefficients over the (r, σ) the training data cover (σ in the learned flow)",
            ["coefficient", "median", "range", LAPLACE_COLUMN],
            rows,
        )
    ]
    cov = coef["_coverage"]
    sections.append(
        f"covered: r {fmt(cov['r_min'])} – {fmt(cov['r_max'])} m, σ {fmt(cov['sigma_min'])} – "
        f"{fmt(cov['sigma_max'])} m/s; no ground truth: these are estimates, not recovery errors"
    )
    if dataset.known_forcing:
        sections.append(drag_note(cov["sigma_min"]))
    else:
        sections.append(
            "note: no known forcing in the data (no Fx, Fy, or all zero) — the added masses and drag "
            "coefficients above are NOT determined by the data (scaling inertia and drag together "
            "changes nothing a neutrally buoyant body does); what is identifiable are the ratios, "
            "drag/(M + m_a) most tightly (the relative velocity's relaxation rate [1/s] at each σ; its "
            "split between c_q and c_l rests on the slowest relative speeds in the data)."
            + held_masses_note(model)
            + " The ratios:"
        )
        ratio_rows = [
            [
                n,
                fmt(r["median"]),
                f"{fmt(r['learned_min'])} – {fmt(r['learned_max'])}",
                laplace_text(laplace, n),
            ]
            for n, r in coef["_ratios"].items()
        ]
        sections.append(
            TableData(
                "identifiable ratios over the covered (r, σ)",
                ["ratio", "median", "range", LAPLACE_COLUMN],
                ratio_rows,
            )
        )
    note = identifiability_note(laplace) if laplace else None
    if note:
        sections.append(note)
    sections.append("written: " + ", ".join(str(f) for f in written))
    return Inspection("learned", coef, None, sections, written)


def _ensemble(fit: Fit, figures: bool) -> Inspection:
    """An ensemble: each coefficient and ratio with the members' median and 90 % interval; with
    ``figures`` each member's flow and coefficient figures in its own folder."""
    models, dataset, folder = fit.models, fit.dataset, fit.folder
    truth = None if dataset.imported else dataset.equations()
    rows = ensemble_intervals([m.eom for m in models], dataset, truth)
    written = _exports(models, dataset, folder)
    if figures:
        for run, model in zip(fit.runs, models, strict=True):
            written += flow_figure(model.flow, truth.flow if truth else None, dataset, run.folder / "flow")
            written += coefficient_figure(
                model.coefficients,
                truth.coefficients if truth else None,
                dataset,
                run.folder / "coefficients",
                flow_of=None if truth else model.eom,
            )
    forced = dataset.known_forcing
    columns = ["quantity", "median", "90 % interval", "rel. width"]
    if truth is not None:
        columns += ["true", "truth inside", "max rel. error"]
    cells = []
    for name, r in rows.items():
        row = [with_unit(name), fmt(r["median"]), f"{fmt(r['lo'])} – {fmt(r['hi'])}", f"{r['rel_width']:.1%}"]
        if truth is not None:
            row += [fmt(r["true"]), f"{r['coverage']:.0%} of points", f"{r['max_rel']:.2%}"]
        cells.append(row)
    title = (
        f"ensemble of {len(models)} runs: median and 90 % interval from the members, "
        "typical over the covered (r, σ)"
    )
    sections: list[str | TableData] = [TableData(title, columns, cells)]
    if forced:
        sections.append(drag_note(visited_r_sigma(models[0].eom, dataset)[:, 1].min()))
    else:
        # without known forces inertia and drag scale together: the members agree on the ratios
        mass_width = max(rows[n]["rel_width"] for n in ("m_ax", "m_ay"))
        ratio_width = max(rows[n]["rel_width"] for n in rows if "/" in n)
        drag_width = max(rows[n]["rel_width"] for n in rows if n.startswith("drag/"))
        sections.append(
            "note: no known forcing in the data — the added masses and drag coefficients are NOT "
            "determined by the data; only the ratios c/(M + m_a) are (the members' masses spread "
            f"{mass_width:.1%}, their ratios {ratio_width:.1%}; the total drag's, drag/(M + m_a), "
            f"{drag_width:.1%}: the split between c_q and c_l rests on the slowest relative speeds)."
            + held_masses_note(models[0])
        )
    bootstrap = all(r.train_config.bootstrap for r in fit.runs)
    sections.append(
        f"the interval: the members' mean ± t({0.5 + LEVEL / 2:g}; {len(models) - 1}) · s · "
        f"√(1 + 1/{len(models)}) "
        + (
            "— members trained on bootstrap weightings of the data, so it holds the data's sampling "
            "noise and the initialisation's, not a bias that every member shares (such as the "
            "split of the drag between c_q and c_l)"
            if bootstrap
            else "— members trained on the same data: it holds their initialisation and batch order, "
            "not the data's sampling noise"
        )
    )
    sections.append("written: " + ", ".join(str(f) for f in written))
    return Inspection("ensemble", rows, None, sections, written, members=len(models), forced=forced)


def _recovery(fit: Fit, figures: bool) -> Inspection:
    """On simulated data: the learned coefficients and flow against the truth."""
    run, dataset = fit.runs[0], fit.dataset
    model, folder = fit.models[0], run.folder
    coef = coefficient_recovery(model.coefficients, dataset)
    flow = flow_recovery(model.flow, dataset)
    truth = dataset.equations()
    laplace = laplace_intervals(model, dataset, run.train_config, truth.coefficients)
    coef["_laplace"] = laplace
    written = _exports([model], dataset, folder)
    if figures:
        written += flow_figure(model.flow, truth.flow, dataset, folder / "flow")
        written += coefficient_figure(
            model.coefficients, truth.coefficients, dataset, folder / "coefficients"
        )
    init = dict(zip(("m_ax", "m_ay", "c_q", "c_l"), run.model_config.init_coefficients, strict=True))
    coef["_near_initial"] = [
        n
        for n, v in init.items()
        if max(abs(coef[n]["learned_min"] - v), abs(coef[n]["learned_max"] - v)) < 0.05 * v
    ]
    sections: list[str | TableData] = [_recovery_table(coef)]
    if dataset.actuation != "none":  # unforced, even the total drag is fixed only relative to inertia
        sections.append(drag_note(coef["_coverage"]["sigma_min"]))
    sections.append(_bands_table(coef))
    if laplace is not None:
        sections.append(_laplace_table(laplace))
        note = identifiability_note(laplace)
        if note:
            sections.append(note)
    still = coef["_near_initial"]
    if still:
        sections.append(
            f"note: {', '.join(still)} still lie within 5 % of their initial values "
            f"({', '.join(f'{n} = {init[n]:g}' for n in still)}): training has barely moved them, so they "
            "say little yet; train longer (fhnn train ... --steps N --extend)."
        )
    if dataset.actuation == "none":
        sections.append(
            "note: trained without actuation — only the ratios c / (M + m_a) are identifiable, the "
            "total drag's drag / (M + m_a) most tightly; the absolute masses and drag coefficients "
            "above are not measured quantities."
            + held_masses_note(model)
            + " The ratios: "
            + ", ".join(
                f"{name} {r['mean_rel']:.2%} mean / {r['max_rel']:.2%} max rel. error"
                for name, r in coef["_ratios"].items()
            )
        )
    when = (
        f", {len(flow['times'])} times over {flow['times'][0]:g}–{flow['times'][-1]:g} s"
        if len(flow["times"]) > 1
        else ""
    )
    sections.append(f"flow: relative L2 error {flow['rel_l2']:.3%} over {flow['points']} grid points{when}")
    sections.append("written: " + ", ".join(str(f) for f in written))
    return Inspection("recovery", coef, flow, sections, written)


def _recovery_table(coef: dict[str, Any]) -> TableData:
    rows = []
    for name in ("m_ax", "m_ay", "c_q", "c_l", "_drag"):
        c = coef[name]
        rows.append(
            [
                with_unit(name.strip("_")),
                f"{fmt(c['learned_min'])} – {fmt(c['learned_max'])}",
                f"{fmt(c['true_min'])} – {fmt(c['true_max'])}",
                f"{c['mean_rel']:.2%}",
                f"{c['max_rel']:.2%}",
            ]
        )
    return TableData(
        "coefficients over the (r, σ) the training data covers",
        ["coefficient", "learned range", "true range", "mean rel. error", "max rel. error"],
        rows,
    )


def _laplace_table(laplace: dict[str, dict[str, Any]]) -> TableData:
    rows = [
        [
            with_unit(name),
            fmt(r["median"]),
            laplace_text(laplace, name),
            fmt(r["true"]),
            "–" if r["inside"] is None else ("yes" if r["inside"] else "no"),
        ]
        for name, r in laplace.items()
    ]
    return TableData(
        "medians over the covered (r, σ) with 90 % intervals from the whole-track fit's curvature "
        "(the data's noise, given the model's structure)",
        ["quantity", "median", LAPLACE_COLUMN, "true median", "truth inside"],
        rows,
    )


def _bands_table(coef: dict[str, Any]) -> TableData:
    rows = [
        [
            f"{fmt(b['sigma_lo'])} – {fmt(b['sigma_hi'])}",
            str(b["points"]),
            f"{b['quadratic_share']:.1%}",
            f"{b['c_q']:.2%}",
            f"{b['drag']:.2%}",
        ]
        for b in coef["_by_sigma"]
    ]
    return TableData(
        "c_q by σ band (quantiles of the visited σ); small quadratic share: c_q weakly constrained",
        ["σ [m/s]", "points", "quadratic share of drag", "c_q max rel. error", "drag max rel. error"],
        rows,
    )
