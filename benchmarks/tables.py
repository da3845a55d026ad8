"""The Markdown the documentation shows from the result files, made at site build time
(``docs/hooks.py``) and for the README (``benchmarks/regenerate.py``); never typed by hand.

Each ``render_NAME(record)`` turns ``benchmarks/results/NAME*.json`` into Markdown; a result file
without a renderer of its own is shown by :func:`render_printed` (what its script printed) or
:func:`render_numbers` (its numbers, flattened)."""

from __future__ import annotations

import json
import math
import textwrap
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def _g(value: float | None, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    if value == 0 or 1e-2 <= abs(value) < 1e4:
        return f"{value:.{digits}g}"
    mantissa, exponent = f"{value:.{digits - 1}e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _ratio(value: float) -> str:
    """Two significant digits, without an exponent (330, 68, 2.1)."""
    return f"{float(f'{value:.2g}'):g}"


def _pct(value: float | None, digits: int = 2) -> str:
    if value is None or not math.isfinite(value):
        return "—"
    return f"{100 * value:.{digits}g} %"


def _table(header: list[str], rows: list[list[str]], right: int = 1) -> str:
    align = ["---"] * right + ["---:"] * (len(header) - right)
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join(align) + " |"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def stamp_line(record: dict[str, Any], name: str, folder: str = "benchmarks/results") -> str:
    """Which file, which commit and code, which machine, when."""
    made = record.get("provenance") or {}
    machine = made.get("machine") or {}
    seed = ""
    if "seed_role" in record and "data_seed" in record:
        seed = f" Data seed {record['data_seed']}: a {record['seed_role']} seed."
    elif "seed_role" in record:
        seed = f" Data seeds {', '.join(map(str, record['data_seeds']))}: {record['seed_role']} seeds."
    return (
        f"*From `{folder}/{name}.json`: commit `{str(made.get('commit'))[:10]}`, source "
        f"`{made.get('source')}`, {machine.get('cpu', '?')} ({machine.get('cores', '?')} cores), "
        f"{str(made.get('date', ''))[:10]}.{seed}*"
    )


def render_fhnn_targets(record: dict[str, Any]) -> str:
    """FHNN as ``fhnn train`` trains it by default against the accuracy and recovery targets."""
    targets = record["targets"]
    rows = []
    for scenario in ("solid_body_vortex", "steady_vortex"):
        if scenario not in record:
            continue
        res = record[scenario]
        for h, target in targets[scenario]["rmse_pos"].items():
            value = res["metrics"][h]["rmse_pos"]
            rows.append(
                [
                    scenario,
                    f"RMSE(pos) at {h} s [m]",
                    _g(value),
                    _g(target),
                    "met" if value <= target else "missed",
                ]
            )
        if "coefficients" in res:
            limit = targets[scenario]["coefficients_max_rel"]
            for name in ("m_ax", "m_ay", "c_l", "c_q"):
                value = res["coefficients"][name]["max_rel"]
                rows.append(
                    [
                        scenario,
                        f"{name}, largest relative error",
                        _pct(value),
                        _pct(limit),
                        "met" if value <= limit else "missed",
                    ]
                )
            value, limit = res["flow"]["rel_l2"], targets[scenario]["flow_rel_l2"]
            rows.append(
                [
                    scenario,
                    "flow, relative L2",
                    _pct(value),
                    _pct(limit),
                    "met" if value <= limit else "missed",
                ]
            )
        rows.append(
            [
                scenario,
                "training time [s]",
                f"{res['seconds']:.0f}",
                "600",
                "met" if res["seconds"] <= 600 else "missed",
            ]
        )
    return _table(["data", "quantity", "ours", "target", ""], rows, right=2)


#: The own-data benchmark's targets (issue 14's): mean relative error of each coefficient, the
#: flow's relative L2 error, and RMSE(pos) of ``fhnn predict`` at 5 s against the truth [m].
OWN_DATA_TARGETS = {"coefficients": 0.03, "flow": 0.02, "forecast_5s": 5e-3}


def render_own_data(record: dict[str, Any]) -> str:
    """One own-data run: what the import saw, recovery against the truth, forecasts."""
    t = OWN_DATA_TARGETS
    rows = [
        ["position noise seen [mm] (true 1 mm)", _g(1e3 * record["position_noise_seen"]), ""],
        ["velocity RMS error [mm/s]", _g(1e3 * record["velocity_rms_error"]), ""],
    ]
    for name, value in record["coefficients_mean_rel"].items():
        rows.append([f"{name}, mean relative error", _pct(value), _pct(t["coefficients"])])
    for name, value in record["ratios_mean_rel"].items():
        rows.append([f"{name}, mean relative error", _pct(value), ""])
    rows.append(["flow, relative L2", _pct(record["flow_rel_l2"]), _pct(t["flow"])])
    forecast = record["test_forecasts"]["rmse_pos_vs_truth"]
    rows.append(["`fhnn predict`, RMSE(pos) at 1 s [m]", _g(forecast["1"]), ""])
    rows.append(["`fhnn predict`, RMSE(pos) at 5 s [m]", _g(forecast["5"]), _g(t["forecast_5s"])])
    rows.append(["training time [s]", _g(record["train_seconds"]), ""])
    return _table(["quantity", "ours", "target"], rows)


def render_held_thrust(record: dict[str, Any]) -> str:
    """Held thrust against forces logged at the samples: forecast errors at 5 and 15 s (median
    over the test tracks, against the truth), and the band check on validation tracks."""
    labels = {"held": "thrust held between switches", "logged": "forces logged at the samples"}
    forecasts = {
        "forecast_mm_held_switches": "held switch times",
        "forecast_mm_logged_forces": "logged, interpolated",
    }
    rows = []
    for key, run in record["runs"].items():
        band = run["band_check"]
        for field, how in forecasts.items():
            if field in run:
                rows.append(
                    [
                        labels.get(key, key),
                        how,
                        _g(run[field]["5 s"]),
                        _g(run[field]["15 s"]),
                        f"{band['coverage']:.0%} → widened {band['scale']:.2f}×",
                    ]
                )
    header = ["trained on", "forecast forcing", "5 s [mm]", "15 s [mm]", "90 % band held (validation)"]
    return _table(header, rows, right=2)


def render_time_budget(record: dict[str, Any]) -> str:
    """``--max-time`` against the wall clock of the whole command."""
    rows = [
        [
            f"`{case['command']}`",
            f"{case['budget']:.0f}",
            f"{case['seconds']:.1f}",
            f"{case['bound']:.0f}",
            "within" if case["within"] else "over",
        ]
        for case in record["cases"].values()
    ]
    text = _table(["command", "budget [s]", "took [s]", "bound [s]", ""], rows)
    cont = record.get("continued")
    if cont:
        stops = ", ".join(
            f"{a:,} → {b:,}" for a, b in zip(cont["adam_stopped"], cont["adam_after"], strict=False)
        )
        checks = "; ".join(
            f"{name}: {'held' if held else '**failed**'}" for name, held in cont["checks"].items()
        )
        text += (
            "\n\nThe cut ensemble, continued by the same command (Adam steps per member, at the cut → "
            f"after the second command): {stops}. Checks: {checks}."
        )
    return text


def render_baselines(record: dict[str, Any]) -> str:
    """Every model under the same training, RMSE(pos) at 1 and 5 s (with the plan search's pick
    where the models' plans were searched)."""
    searched = any(
        res.get("chosen", "default") != "default"
        for scenario in ("solid_body_vortex", "steady_vortex")
        for res in record.get(scenario, {}).values()
    )
    rows = []
    for scenario in ("solid_body_vortex", "steady_vortex"):
        for kind, res in record.get(scenario, {}).items():
            cells = []
            for h in ("1", "5"):
                m = res["spec"][h]
                text = _g(m["rmse_pos"])
                if m.get("diverged"):
                    text += f" ({m['diverged']} div.)"
                cells.append(text)
            extra = [res.get("chosen", "default")] if searched else []
            rows.append([scenario, kind, *extra, *cells, *([] if searched else [f"{res['seconds']:.0f}"])])
    if searched:
        caption = (
            f"*Trained as: {record['trained_as']}. The chosen setting is the one with the lowest "
            "validation loss.*"
        )
        header = ["data", "model", "chosen on val", "RMSE(pos) 1 s [m]", "RMSE(pos) 5 s [m]"]
    else:
        caption = (
            f"*Trained as: {record['trained_as']}; no model's size or plan was tuned for this table. "
            "train [s]: wall clock on a machine shared with other work.*"
        )
        header = ["data", "model", "RMSE(pos) 1 s [m]", "RMSE(pos) 5 s [m]", "train [s]"]
    table = _table(header, rows, right=3 if searched else 2)
    return table + "\n\n" + caption


def render_differentiators(record: dict[str, Any]) -> str:
    """Velocity estimators on the tracker's tables: RMS error over all samples and near the ends."""
    rows = []
    for label, r in record["estimators"].items():
        params = dict(r["params"])
        gap = params.pop("max_abs_difference_from_fhnn_kalman_m_per_s", None)
        note = ", ".join(f"{k}={_g(v) if isinstance(v, float) else v}" for k, v in params.items())
        if gap is not None:
            note = f"max. {_g(gap * 1e3)} mm/s from fhnn's Kalman"
        rows.append([label, _g(r["rms"] * 1e3), _g(r["edge_rms"] * 1e3), f"{r['seconds']:.1f}", note])
    caption = (
        f"*{record['tracks']} tracks, {record['samples']} samples, noise {record['noise_m'] * 1e3:g} mm; "
        "seconds include compilation.*"
    )
    header = ["estimator", "velocity RMS [mm/s]", "first/last 0.5 s [mm/s]", "seconds", "parameters"]
    return _table(header, rows) + "\n\n" + caption


#: The solvers of ``benchmarks/track_fit_solvers.py``, in words.
TRACK_SOLVERS = {
    "trackfit": "fhnn TrackFit",
    "qr": "optimistix + QR",
    "cg": "optimistix + Normal(CG)",
    "lsmr": "optimistix + LSMR",
}


def render_track_fit_solvers(record: dict[str, Any]) -> str:
    """The whole-track fit's Levenberg–Marquardt against optimistix's on the same problems."""
    rows = [
        [
            str(r["tracks"]),
            str(r["width"]),
            f"{r['model_params']} + {4 * r['tracks']}",
            str(r["residuals"]),
            TRACK_SOLVERS.get(r["solver"], r["solver"]),
            f"{r['first_s']:.1f}",
            f"{r['per_iter_s']:.3g}",
            str(r["iterations"]),
            _g(r["mean_square"]),
        ]
        for r in record["rows"]
    ]
    header = ["tracks", "width", "parameters", "residuals", "solver", "first [s]", "per iteration [s]"]
    return _table([*header, "iterations", "mean square [m²]"], rows, right=5)


def render_frame_invariance(record: dict[str, Any]) -> str:
    """The default pipeline on the same tracks moved, turned or drawn again, against the original."""
    rows = [
        [variant, _pct(d["flow"]), _pct(d["coefficients"]), _pct(d["forecast"])]
        for variant, d in record["relative_difference_to_original"].items()
    ]
    return _table(["against the original run", "flow", "coefficients", "forecast"], rows)


def render_reproduction(record: dict[str, Any]) -> str:
    """A reproduction's T4 (FHNN RMSE(pos) at 5 s per scenario, T2's for the paper's
    configuration, the paper beside) and T6
    (largest relative error of each coefficient and the flow, mean ± std over the seeds)."""
    cells = record["cells"]
    metrics = ("m_ax", "m_ay", "c_l", "c_q", "flow")
    rows: dict[str, dict[str, str]] = {}
    for r in cells:
        # T4's 5 s cell; for the paper's configuration (no T4 row) T2's 5 s cell, its paper beside
        five_s = r["table"] == "T4" or (r["table"] == "T2" and r["horizon"] == 5)
        if five_s and (r["model"], r["metric"]) == ("fhnn", "rmse_pos"):
            text = (
                f"{_g(r['mean'])} ± {_g(r['std'], 2)}"
                if r["statistic"] == "mean"
                else f"median {_g(r['mean'])}"
            )
            paper = f" ({_g(r['paper'])})" if r.get("paper") is not None else ""
            row = rows.setdefault(r["data"], {})
            if r["table"] == "T4" or "T4" not in row:
                row["T4"] = f"{text}{paper}"
        if r["table"] == "T6" and r["metric"] in metrics and r["mean"] is not None:
            text = f"{_g(100 * r['mean'], 2)} ± {_g(100 * r['std'], 2)}"
            if r["diverged"]:
                text += f" ({r['diverged']}/{r['rollouts']} seeds non-finite)"
            rows.setdefault(r["data"], {})[r["metric"]] = text
    header = ["data", "RMSE(pos) 5 s [m] (paper)", *(f"{m} [%]" for m in metrics)]
    body = [[d, row.get("T4", "—"), *(row.get(m, "—") for m in metrics)] for d, row in rows.items()]
    return _table(header, body)


def render_laplace_exact(record: dict[str, Any]) -> str:
    """Laplace sd against the estimates' spread over noise draws, where FHNN holds the truth."""
    rows = [
        [
            name,
            _g(r["true"], 4),
            _g(r["mean_estimate"], 4),
            _g(r["spread"]),
            _g(r["mean_laplace_sd"]),
            f"{r['spread_over_sd']:.2f}",
            _pct(r["holds"]),
        ]
        for name, r in record["coefficients"].items()
    ]
    header = ["coefficient", "true", "mean estimate", "spread", "Laplace sd", "spread / sd", "90 % holds"]
    caption = (
        f"*{record['draws']} draws of {record['noise'] * 1e3:g} mm noise, {record['iterations']} "
        f"Levenberg–Marquardt iterations each, eigenvalue floor {record['floor']:g}.*"
    )
    return _table(header, rows) + "\n\n" + caption


def render_calibration(record: dict[str, Any]) -> str:
    """Coverage over data sets at the default eigenvalue floor (Laplace), or the members' (ensemble)."""
    if record.get("method") != "laplace":
        return render_numbers(record)
    floors = list(record["summary"])
    floor = next((f for f in floors if float(f) == 1e-16), floors[0])
    table = record["summary"][floor]
    n = len(record["data_seeds"])
    withheld = max(r["withheld"] for r in table.values())
    header = ["quantity", "holds the truth", "marked weak", "median width", "median error", "median |z|"]
    rows = [
        [
            name,
            f"{round(r['holds'] * n)} of {n}",
            f"{round(r['weak'] * n)} of {n}",
            _pct(r["median_rel_width"]),
            _pct(r["median_rel_error"]),
            f"{r['median_z']:.2f}" if math.isfinite(r["median_z"]) else "withheld",
        ]
        for name, r in table.items()
    ]
    caption = (
        f"*{n} data sets ({record['seed_role']} seeds {record['data_seeds'][0]}–"
        f"{record['data_seeds'][-1]}"
        + (", positions only: no known thrust" if record.get("no_forcing") else ", with the known thrust")
        + "), one `fhnn train` run each and its Laplace intervals at the "
        f"eigenvalue floor {float(floor):g} (`fhnn inspect`'s); a 90 % interval should hold the true "
        "value in about 9 of 10, and |z| (the error over the interval's sd) has median 0.67 when the "
        "intervals are honest; *marked weak*: its variance mostly from directions the data barely "
        "constrain, as `fhnn inspect` says. Widths and errors relative to the true value; "
        + (
            "no interval was withheld (wider than its value). "
            if withheld == 0
            else f"at most {round(withheld * n)} of {n} withheld (wider than their value). "
        )
        + f"The file also holds floors {', '.join(f'{float(f):g}' for f in floors if f != floor)}.*"
    )
    return _table(header, rows) + "\n\n" + caption


def render_calibration_discrepancy(record: dict[str, Any]) -> str:
    """The Laplace intervals with and without the model-discrepancy sd ``b``, rescored from the
    calibration benchmark's stored rows (``benchmarks/calibration_discrepancy.py``)."""
    b = record["chosen"]
    key = f"{b:g}"
    cases = (
        {"forcing": {"0": record["scored"]["0"], key: record["scored"][key]}}
        if record["seed_role"] == "choosing"
        else record["scored"]
    )
    header = ["quantity", "holds, b = 0", f"holds, b = {key}", "median width", "× curvature", "median |z|"]
    out = []
    for case, tables in cases.items():
        plain, wide = tables["0"], tables[key]
        rows = [
            [
                name,
                f"{plain[name]['held']} of {plain[name]['given']}" if plain[name]["given"] else "withheld",
                f"{r['held']} of {r['given']}" if r["given"] else "withheld",
                _pct(r["median_rel_width"]),
                _g(r["median_width_over_curvature"]),
                _g(r["median_z"]),
            ]
            for name, r in wide.items()
        ]
        title = {"forcing": "with the known thrust", "no_forcing": "positions only"}.get(case, case)
        out.append(f"**{title}**\n\n" + _table(header, rows))
    if record["seed_role"] == "choosing":
        grid = ", ".join(f"{g}: {min(r['held'] for r in t.values())}" for g, t in record["scored"].items())
        caption = (
            f"*Choosing data sets {record['data_seeds'][0]}–{record['data_seeds'][-1]} at floor "
            f"{record['floor']}; the fewest data sets of 10 any quantity holds, per b: {grid}. "
        )
    else:
        caption = (
            "*Confirming data sets "
            + "; ".join(f"{c}: `{v['file']}` at {v['commit'][:7]}" for c, v in record["sources"].items())
            + ", rescored once. "
        )
    caption += (
        f"b = {key} is the rule's choice; widths relative to the true value, × curvature the "
        "widened interval's width over the curvature's alone; |z| is the error over the widened "
        "sd (0.67 in the median when honest).*"
    )
    return "\n\n".join(out) + "\n\n" + caption


def render_turning_track_fit(record: dict[str, Any]) -> str:
    """A pose fit after the one-step training, on a choosing seed's validation split."""
    one = record["one_step"]["val_forecast"]
    rows = [["one-step model", "—", "—", "—", _g(one["rmse_pos"]), _g(one["rmse_heading"])]]
    for window, f in record["track_fits"].items():
        rows.append(
            [
                f"{window} s windows, starts {record.get('starts', 'fitted')}",
                f"{_g(f['objective_first_last'][0])} → {_g(f['objective_first_last'][1])}",
                f"{_g(f['val_misfit_before'])} → {_g(f['val_misfit_after'])}",
                "kept" if f["kept"] else "rejected",
                _g(f["val_forecast"]["rmse_pos"]),
                _g(f["val_forecast"]["rmse_heading"]),
            ]
        )
    header = ["model", "training misfit", "validation misfit", "guard", "RMSE(pos) 5 s [m]", "heading [rad]"]
    caption = (
        f"*`{record['scenario']}`, data seed {record['data_seed']} ({record['seed_role']}), "
        f"{record['steps']} L-BFGS iterations; misfits are mean squared pose residuals over the "
        "noise floor (1e-6 m, noise-free data); the forecasts are the kept model's, on the "
        "validation split from its true first states.*"
    )
    return _table(header, rows) + "\n\n" + caption


def _turning_val_cells(run: dict[str, Any]) -> list[str]:
    """A 3-DOF training's validation loss, validation forecast errors and training seconds."""
    val = run["val_forecast"]
    return [_g(run["val_loss"]), _g(val["rmse_pos"]), _g(val["rmse_heading"]), f"{run['train_seconds']:.0f}"]


#: The columns of :func:`_turning_val_cells`.
TURNING_VAL_HEADER = ["validation loss", "val RMSE(pos) 5 s [m]", "val heading [rad]", "training [s]"]


def render_turning_coverage(record: dict[str, Any]) -> str:
    """The 3-DOF defaults trained on more trajectories, judged on the data seed's validation split."""
    header = ["training trajectories", *TURNING_VAL_HEADER]
    rows = [[str(run["train_trajectories"]), *_turning_val_cells(run)] for run in record["runs"].values()]
    extra = ", ".join(str(s) for s in record["extra_seeds"])
    caption = (
        f"*`{record['scenario']}`, data seed {record['data_seed']} ({record['seed_role']}); the "
        f"larger set adds the training trajectories of auxiliary seed(s) {extra}. Each model's "
        "validation loss is on the same validation trajectories, scaled by its own training "
        "split's RMS rates; the forecasts "
        f"from the true first states, at {record['horizon']:g} s.*"
    )
    return _table(header, rows) + "\n\n" + caption


def render_turning_lbfgs_pairs(record: dict[str, Any]) -> str:
    """The 3-DOF training with more pairs in its L-BFGS phase, one row per pair count."""
    confirming = record["seed_role"] == "confirming"
    header = ["L-BFGS pairs", *TURNING_VAL_HEADER]
    if confirming:
        header += ["test RMSE(pos) 5 s [m]", "test heading [rad]"]
    rows = []
    for pairs, run in record["runs"].items():
        row = [f"{int(pairs):,}", *_turning_val_cells(run)]
        if confirming:
            row += [_g(run["test"]["forecast"]["rmse_pos"]), _g(run["test"]["forecast"]["rmse_heading"])]
        rows.append(row)
    caption = (
        f"*`{record['scenario']}`, data seed {record['data_seed']} ({record['seed_role']}), "
        f"{record['train_pairs']:,} training pairs; the forecasts from the true first states, "
        f"at {record['horizon']:g} s.*"
    )
    return _table(header, rows) + "\n\n" + caption


def render_track_budget(record: dict[str, Any]) -> str:
    """The whole-track fit's sample budget on the own-data choosing seeds: one row per budget."""
    seeds = [str(s) for s in record["data_seeds"]]
    header = ["`train.track_samples`", "tracks fitted", "val forecast 5 s [mm], per seed"]
    header += ["÷ default (gmean)", "training [s]", "`c_l` error [%]", "drag error [%]", "flow error [%]"]
    timed = record.get("normal_equations_seconds", {})
    if timed:
        header.insert(2, f"one Gauss–Newton system [s] (seed {record['timed_on']}, alone)")
    confirming = record["seed_role"] == "confirming"
    if confirming:
        header.append("test forecast 5 s [mm]")
    rows = []
    for budget, runs in record["runs"].items():
        per = [runs[s] for s in seeds]
        ratio = record["ratios"].get(budget)
        mean = lambda f, per=per: float(sum(map(f, per)) / len(per))  # noqa: E731
        rows.append(
            [
                f"{int(budget):,}" + (" (default)" if int(budget) == record["default"] else ""),
                "/".join(str(r["fit_tracks"]) for r in per),
                *([f"{timed[budget]:.1f}"] if timed else []),
                " / ".join(f"{r['val_forecast_5s'] * 1e3:.4f}" for r in per),
                f"{ratio['gmean']:.4f}" if ratio else "1",
                f"{mean(lambda r: r['train_seconds']):.0f}",
                f"{mean(lambda r: r['truth']['coefficients_mean_rel']['c_l']) * 100:.2f}",
                f"{mean(lambda r: r['truth']['drag_mean_rel']) * 100:.3f}",
                f"{mean(lambda r: r['truth']['flow_rel_l2']) * 100:.3f}",
            ]
            + ([f"{mean(lambda r: r['truth']['test_forecast_5s']) * 1e3:.3f}"] if confirming else [])
        )
    if confirming:
        verdict = "confirmed" if record["confirmed"] else "not confirmed"
        said = f"Own-data seed {', '.join(seeds)}, confirming {int(record['chosen']):,}: {verdict}"
    else:
        said = f"Own-data choosing seeds {', '.join(seeds)}; chosen: {int(record['chosen']):,}"
    caption = (
        f"*{said} (validation forecast ratio at most {record['forecast_slack']:g}). Training time and "
        "the errors against the simulator's truth (means over the seeds) choose nothing; the runs "
        "shared the 2 cores, two to four at a time, so their training times do not compare.*"
    )
    return _table(header, rows) + "\n\n" + caption


def render_turning(record: dict[str, Any]) -> str:
    """The 3-DOF model on its own scenarios against issue 71's targets (× the target where missed)."""
    runs, targets = record["runs"], record["targets"]

    def cell(value: float, target: float) -> str:
        return _g(value) + ("" if value <= target else f" ({_ratio(value / target)}×)")

    def pct_cell(value: float, target: float) -> str:
        return _pct(value) + ("" if value <= target else f" ({_ratio(value / target)}×)")

    measures = [
        ("RMSE(pos) at 5 s [m]", lambda r: cell(r["forecast"]["rmse_pos"], targets["rmse_pos"]), "1e-4"),
        (
            "RMSE(heading) at 5 s [rad]",
            lambda r: cell(r["forecast"]["rmse_heading"], targets["rmse_heading"]),
            "1e-3",
        ),
        *[
            (name, lambda r, n=name: pct_cell(r["added_mass"][n]["rel_error"], targets["added_mass"]), "2 %")
            for name in ("m_11", "m_22", "m_66")
        ],
        *[
            (
                f"damping, {axis} (L2)",
                lambda r, a=axis: pct_cell(r["damping"][a]["rel_l2"], targets["damping"]),
                "5 %",
            )
            for axis in ("surge", "sway", "yaw")
        ],
        ("flow (L2)", lambda r: pct_cell(r["flow"]["rel_l2"], targets["flow"]), "1 %"),
        ("training [s]", lambda r: f"{r['train_seconds']:.0f}", "—"),
    ]
    header = ["measure", *[f"`{n}`" for n in runs], "target"]
    rows = [[label, *[fn(r) for r in runs.values()], target] for label, fn, target in measures]
    return _table(header, rows)


def _interval_rows(quantities: list[dict[str, Any]]) -> list[list[str]]:
    rows = []
    for q in quantities:
        holds = "yes" if q["inside"] else "**no**"
        if "band_holds" in q:
            holds += f" (pointwise band: {100 * q['band_holds']:.0f} %)"
        rows.append(
            [
                f"`{q['name']}`",
                _g(q["true"], 4),
                _g(q["median"], 4),
                _pct(q["rel_error"]),
                f"{_g(q['lo'], 4)} to {_g(q['hi'], 4)}",
                _pct(q["rel_width"]),
                holds,
            ]
        )
    return rows


def _member_forecasts(forecasts: list[dict[str, Any]]) -> str:
    return ", ".join(f"{f['member']} {_g(f['rmse_pos'])} m / {_g(f['rmse_heading'])} rad" for f in forecasts)


def render_turning_intervals(record: dict[str, Any]) -> str:
    """A turning body's ensemble intervals against the truth on one data set (and, after a track
    fit of each member, again)."""
    header = ["quantity", "true", "median", "error", "90 % interval", "width", "holds the truth"]
    if record.get("route") == "table":
        noise = (
            f"noise {_g(record['obs_noise'])} on the observed positions [m] and heading [rad] only, "
            "imported as a user's table (poses smoothed, velocities estimated)"
        )
        scored = "against the observed poses"
    else:
        noise = f"noise {_g(record['obs_noise'])} on every state entry"
        scored = "against the truth"
    caption = (
        f"`{record['scenario']}`, data seed {record['data_seed']} ({record['seed_role']}), {noise}, "
        f"{record['members']} members; the members' RMSE(pos) / RMSE(heading) at 5 s {scored}: "
        f"{_member_forecasts(record['forecasts'])}."
    )
    text = caption + "\n\n" + _table(header, _interval_rows(record["quantities"]))
    if "track_fit" in record:
        tracked = record["track_fit"]
        fits = "; ".join(
            f"{f['member']} objective {_g(f['objective_first'])} → {_g(f['objective_last'])}, validation "
            f"misfit {_g(f['val_before'])} → {_g(f['val_after'])}, {'kept' if f['kept'] else 'rejected'}"
            for f in tracked["fits"]
        )
        text += (
            f"\n\nEach member then fitted to its bootstrap's observed poses (track fit: "
            f"{_g(tracked['config']['window'])} s windows, {tracked['config']['steps']} L-BFGS iterations; "
            f"noise variances per residual): {fits}. Their RMSE(pos) / RMSE(heading) at 5 s: "
            f"{_member_forecasts(tracked['forecasts'])}.\n\n"
        )
        text += _table(header, _interval_rows(tracked["quantities"]))
    return text


def render_turning_table(record: dict[str, Any]) -> str:
    """The 3-DOF model trained on a noisy, irregular table of its own scenarios."""
    runs = record["runs"]
    measures = [
        ("noise found, position [m]", lambda r: _g(r["import"]["noise_estimate"]["position"])),
        ("noise found, heading [rad]", lambda r: _g(r["import"]["noise_estimate"]["heading"])),
        *[
            (f"estimated {k}, RMS error [{unit}]", lambda r, k=k: _g(r["import"]["rms_state_error"][k]))
            for k, unit in (("u", "m/s"), ("v", "m/s"), ("r", "rad/s"))
        ],
        ("RMSE(pos) at 5 s, against the truth [m]", lambda r: _g(r["forecast_truth"]["rmse_pos"])),
        ("RMSE(pos) at 5 s, against the table [m]", lambda r: _g(r["forecast_observed"]["rmse_pos"])),
        ("RMSE(heading) at 5 s, against the truth [rad]", lambda r: _g(r["forecast_truth"]["rmse_heading"])),
        *[
            (name, lambda r, n=name: _pct(r["added_mass"][n]["rel_error"]))
            for name in ("m_11", "m_22", "m_66")
        ],
        *[
            (f"damping, {axis} (L2)", lambda r, a=axis: _pct(r["damping"][a]["rel_l2"]))
            for axis in ("surge", "sway", "yaw")
        ],
        ("flow (L2)", lambda r: _pct(r["flow"]["rel_l2"])),
        ("training [s]", lambda r: f"{r['train_seconds']:.0f}"),
    ]
    header = ["measure", *[f"`{n}`" for n in runs]]
    rows = [[label, *[fn(r) for r in runs.values()]] for label, fn in measures]
    caption = (
        f"*Table: {record['sampling']}, noise {_g(record['position_noise'])} m on x, y and "
        f"{_g(record['heading_noise'])} rad on the heading; data seed {record['data_seed']} "
        f"({record['seed_role']}).*"
    )
    return caption + "\n\n" + _table(header, rows)


def _track_fit_cell(part: dict[str, Any]) -> str:
    """A track fit's window and whether its guard kept it (``—`` for the one-step model)."""
    if "kept" not in part:
        return "—"
    return f"{part.get('window', 10):g} s, {'kept' if part['kept'] else 'rejected'}"


def _shipmmg_forecast_rows(
    record: dict[str, Any], pos_target: str, heading_target: str, tracks: list[str] | tuple[str, ...] = ()
) -> list[tuple[str, Any, str]]:
    """The shipmmg check's forecast rows, shared by both of its tables: held-out RMSE(pos) (and
    per held-out manoeuvre in ``tracks``), heading, the validation forecast, the normalised RMSE,
    the track fit and the seconds, as ``(label, cell of a stage, target)``."""
    return [
        ("held-out RMSE(pos) over 1-60 s [m]", lambda r: _g(r["forecast"]["rmse_pos_60"]), pos_target),
        *[
            (f"… `{n}`", lambda r, n=n: _g(r["forecast"]["tracks"][n]["rmse_pos_60"]), "")
            for n in tracks
        ],
        ("held-out RMSE(heading) over 1-60 s [°]", lambda r: _g(r["forecast"]["rmse_heading_60_deg"]),
         heading_target),
        ("… from the true first state: RMSE(pos) [m] / heading [°]",
         lambda r: _start_cell(r, "forecast_true_start"), ""),
        ("… from a first state fitted to 10 s (as `fhnn turning predict`): RMSE(pos) [m] / heading [°]",
         lambda r: _start_cell(r, "forecast_fitted_start"),
         f"{pos_target} / {heading_target}" if heading_target else pos_target),
        ("validation RMSE(pos) over 1-60 s, against the observations [m]",
         lambda r: _g(r["val_forecast"]["rmse_pos_60"]) if "val_forecast" in r else "—", ""),
        ("… from first states fitted to 10 s [m]",
         lambda r: _g(r["val_forecast_fitted"]["rmse_pos_60"]) if "val_forecast_fitted" in r else "—", ""),
        ("normalised RMSE over the whole track", lambda r: _pct(r["forecast"]["nrmse_track"]),
         f"published: {_pct(record['published_nrmse'])}"),
        ("track fit: window, guard", _track_fit_cell, ""),
        ("seconds", lambda r: f"{r.get('train_seconds', r.get('seconds', float('nan'))):.0f}", ""),
    ]  # fmt: skip


def _start_cell(r: dict[str, Any], key: str) -> str:
    """The held-out forecasts ``key`` (from other first states), where the run recorded them."""
    if key not in r:
        return "—"
    return f"{_g(r[key]['rmse_pos_60'])} / {_g(r[key]['rmse_heading_60_deg'])}"


def _shipmmg_table(stages: list[tuple[str, Any]], measures: list, caption: str) -> str:
    """``caption`` over a table of ``measures`` (label, cell, target), one column per stage."""
    header = ["measure", *[f"`{n}`" for n, _ in stages], "target"]
    rows = [[label, *[fn(r) for _, r in stages], goal] for label, fn, goal in measures]
    return caption + "\n\n" + _table(header, rows)


def _shipmmg_noise(record: dict[str, Any]) -> str:
    return (
        f"noise {_g(record['position_noise'])} m on x, y and {_g(record['heading_noise'])} rad on the "
        "heading, samples 0.4-0.6 s apart"
    )


def render_shipmmg_controls(record: dict[str, Any]) -> str:
    """The 3-DOF model with a learned actuator map against KVLCC2 in shipmmg: only the rudder
    angle and the propeller speed given; the one-step model and any track fits, forecasts per
    held-out manoeuvre, beside the target."""
    stages = [(n, part) for n, part in record.items() if n.startswith("controls")]
    tracks = list(stages[0][1]["forecast"]["tracks"])
    measures = _shipmmg_forecast_rows(record, _g(record["targets"]["rmse_pos_60"]), "", tracks)
    caption = (
        f"*15 manoeuvres of 90 s, {_shipmmg_noise(record)}; the table logs the rudder angle and the "
        f"propeller speed, no force; damping `{record['damping']}`, nets of width "
        f"{record.get('width') or 'the default (32)'}. Forecasts from each held-out manoeuvre's first "
        "estimated state under its logged controls, scored against shipmmg's noise-free trajectory; "
        "the validation manoeuvres' against their observations.*"
    )
    return _shipmmg_table(stages, measures, caption)


def render_shipmmg(record: dict[str, Any]) -> str:
    """The 3-DOF model against KVLCC2 in shipmmg: the one-step model, the track fits and any chain
    of them over growing windows (``grow_<W>s``, each from the one before) beside the targets."""
    stages = [
        (n, part) for n, part in record.items() if n == "one_step" or n.startswith(("track_fit", "grow_"))
    ]
    targets = record["targets"]
    measures = [
        *[
            (f"added mass {a}", lambda r, a=a: _pct(r["added_mass"][a]["rel_error"]),
             _pct(targets["added_mass"]) if a != "m_11" else "—")
            for a in ("m_11", "m_22", "m_66")
        ],
        *[
            (f"total inertia, {a}", lambda r, a=a: _pct(r["total_inertia"][a]["rel_error"]),
             _pct(targets["total_inertia"]))
            for a in ("m_11", "m_22", "m_66")
        ],
        *_shipmmg_forecast_rows(record, _g(targets["rmse_pos_60"]), _g(targets["rmse_heading_60_deg"])),
    ]  # fmt: skip
    caption = (
        f"*15 manoeuvres of 90 s (held out: {', '.join(record['split']['test'])}), {_shipmmg_noise(record)}; "
        f"damping `{record['damping']}`; errors are relative to shipmmg's values; the forecasts run from "
        "each held-out track's first estimated state under its recorded forcing and are scored against "
        "shipmmg's noise-free trajectory.*"
    )
    return _shipmmg_table(stages, measures, caption)


def render_forecast_floor(record: dict[str, Any]) -> str:
    """shipmmg's own equations forecasting the held-out manoeuvres: from which first state, under
    which forcing, against issue 71's targets."""
    e = record["start_error"]
    rows = [
        [label, _g(record[key]["rmse_pos_60"]), _g(record[key]["rmse_heading_60_deg"]),
         _pct(record[key]["nrmse_track"])]
        for key, label in (
            ("estimated_start", "the import's estimated first state, the table's forcing"),
            ("true_start", "shipmmg's first state, the table's forcing"),
            ("true_start_forcing_every_step", "shipmmg's first state, the forcing every 0.05 s"),
            ("fitted_start", f"a first state fitted to the first {_g(record.get('fit_seconds', 0))} s "
             "of observations, the table's forcing"),
        )
        if key in record
    ]  # fmt: skip
    t = record["targets"]
    rows.append(["target (issue 71)", _g(t["rmse_pos_60"]), _g(t["rmse_heading_60_deg"]), ""])
    caption = (
        f"*Data seed {record['data_seed']}, held out: {', '.join(record['manoeuvres'])}. The estimated "
        f"first states are off by {_g(100 * e['position_m'], 2)} cm, {_g(e['heading_deg'], 2)}°, "
        f"{_g(100 * e['velocity_m_s'], 2)} cm/s and {_g(e['yaw_rate_deg_s'], 2)}°/s (RMS).*"
    )
    header = ["shipmmg's equations from", "RMSE(pos) over 1-60 s [m]", "heading [°]", "normalised RMSE"]
    return caption + "\n\n" + _table(header, rows)


def render_turning_choice(record: dict[str, Any]) -> str:
    """A choice of the 3-DOF model's settings: each run's validation loss (what chose) and more."""
    header = ["scenario", "setting", "validation loss", "last training loss", "training [s]"]
    rows = []
    for r in record["runs"]:
        losses = [_g(r["val_loss"]), _g(r["last_train_loss"])]
        rows.append([f"`{r['scenario']}`", f"`{r['setting']}`", *losses, f"{r['seconds']:.0f}"])
    return _table(header, rows, right=2)


def render_station_keeping(record: dict[str, Any]) -> str:
    """Station keeping under MPC: RMS distance from the station with the learned and true models."""
    ratio = record["ratio"]
    target = record["target_ratio"]
    verdict = "met" if ratio <= target else f"missed by {_ratio(ratio / target)}×"
    rows = [
        ["drifting, no thrust", _g(record["drift"])],
        ["MPC with the true equations", _g(record["true_model"])],
        ["MPC with the learned model", _g(record["learned_model"])],
        ["learned / true", f"{ratio:.3f} (target ≤ {record['target_ratio']:g}: {verdict})"],
    ]
    caption = (
        f"*RMS distance [m] from the station over the last {2 * record['seconds'] / 3:g} s of "
        f"{record['seconds']:g} s; {record['iterations']} L-BFGS iterations per decision; the model "
        f"trained in {record['train_seconds']:.0f} s.*"
    )
    return _table(["controller", "RMS distance [m]"], rows) + "\n\n" + caption


def render_printed(record: dict[str, Any]) -> str:
    """What the script printed."""
    return "```text\n" + record["output"].rstrip() + "\n```"


def _leaves(value: Any, prefix: str = "") -> list[tuple[str, Any]]:
    if isinstance(value, dict):
        out = []
        for k, v in value.items():
            if k not in ("provenance", "commit"):
                out += _leaves(v, f"{prefix}.{k}" if prefix else str(k))
        return out
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return [(prefix, value)]
    return []


def render_numbers(record: dict[str, Any]) -> str:
    """Every number of the file, by its key."""
    return _table(["key", "value"], [[f"`{k}`", _g(v, 4)] for k, v in _leaves(record)])


def render(name: str, record: dict[str, Any], folder: str = "benchmarks/results") -> str:
    """The Markdown of result file ``name`` (without ``.json``) in ``folder``."""
    kinds = (
        "own_data",
        "fhnn_targets",
        "reproduction_faults",  # printed, not the reproduction's tables
        "reproduction",
        "baselines",
        "track_fit_solvers",
        "calibration_discrepancy",
        "calibration",
        "forecast_floor",
        "turning_choice",
        "turning_table",
        "turning_intervals",
        "turning_track_fit",
        "turning_lbfgs_pairs",
        "turning_coverage",
        "turning",
        "track_budget",
        "station_keeping",
        "shipmmg_controls",
        "shipmmg",
    )
    base = next((b for b in kinds if name.startswith(b)), name)
    if f"render_{base}" in globals():
        body = globals()[f"render_{base}"](record)
    elif "output" in record:
        body = render_printed(record)
    else:
        body = render_numbers(record)
    return body + "\n\n" + stamp_line(record, name, folder)


def result(name: str) -> dict[str, Any]:
    """``benchmarks/results/NAME.json``."""
    return json.loads((RESULTS / f"{name}.json").read_text())


def headline(tables: list[dict[str, Any]]) -> str:
    """The README's results table from the reproduction's cells (``docs/reproduction/tables.json``):
    FHNN and the paper's baselines, RMSE(pos) at 1, 5 and 60 s on the two main data sets."""
    rows_spec = [
        ("FHNN, 1 s", "T1", "fhnn", 1),
        ("Neural ODE, 1 s", "T1", "node", 1),
        ("FHNN, 5 s", "T2", "fhnn", 5),
        ("HNN, 5 s", "T2", "hnn", 5),
        ("LNN, 5 s", "T2", "lnn", 5),
        ("DHN, 5 s", "T2", "dhn", 5),
        ("FHNN, 60 s", "T3", "fhnn", 60),
    ]
    rows = []
    for label, table, model, horizon in rows_spec:
        cells, paper = [], None
        for data in ("solid_body_vortex", "steady_vortex"):
            (rec,) = [
                r
                for r in tables
                if (r["table"], r["data"], r["model"], r["horizon"], r["metric"])
                == (table, data, model, horizon, "rmse_pos")
            ]
            paper = rec["paper"]
            if rec["statistic"] == "mean":
                cells.append(f"{_g(rec['mean'])} ± {_g(rec['std'], 2)}")
            elif rec["mean"] is None:
                cells.append(f"diverged ({rec['diverged']}/{rec['rollouts']} rollouts)")
            else:
                cells.append(f"median {_g(rec['mean'])} ({rec['diverged']}/{rec['rollouts']} diverged)")
        rows.append([label, *cells, _g(paper)])
    return _table(["RMSE(pos) [m]", "solid_body_vortex", "steady_vortex (actuated)", "paper"], rows)


def scenario_line(tables: list[dict[str, Any]]) -> str:
    """FHNN's RMSE(pos) at 5 s on each scenario of T4 against the paper's."""
    parts = []
    for rec in (r for r in tables if (r["table"], r["model"], r["metric"]) == ("T4", "fhnn", "rmse_pos")):
        if rec["statistic"] != "mean":
            parts.append(
                f"`{rec['data']}` median {_g(rec['mean'])} ({rec['diverged']}/{rec['rollouts']} diverged)"
            )
            continue
        ratio = rec["paper"] / rec["mean"]
        better = f"{_ratio(ratio)}× better" if ratio >= 1 else f"{_ratio(1 / ratio)}× worse"
        parts.append(
            f"`{rec['data']}` {_g(rec['mean'])} ± {_g(rec['std'], 2)} ({better} than {_g(rec['paper'])})"
        )
    text = "FHNN at 5 s on every scenario (T4): " + ", ".join(parts) + "."
    return textwrap.fill(text, 100, break_on_hyphens=False)


README_BEGIN = "<!-- results: generated by benchmarks/regenerate.py from docs/reproduction/tables.json -->"
README_END = "<!-- /results -->"


def readme_results(tables: list[dict[str, Any]]) -> str:
    """The README's generated results block (between :data:`README_BEGIN` and :data:`README_END`)."""
    return "\n\n".join([README_BEGIN, headline(tables), scenario_line(tables), README_END])
