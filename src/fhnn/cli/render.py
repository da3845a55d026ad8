"""How the CLI prints what the library returns: Rich tables on standard output, notes on
standard error."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from fhnn.api.report import TableData, fmt

stdout = Console()
err = Console(stderr=True)


def note(text: str) -> None:
    """A line on standard error."""
    err.print(text, highlight=False, soft_wrap=True)


def table(data: TableData) -> Table:
    """``data`` as a Rich table: title on the left, every column right-aligned; its text is
    shown as it is (a unit such as ``[kg]`` is not read as Rich markup)."""
    out = Table(title=escape(data.title), title_justify="left")
    for col in data.columns:
        out.add_column(escape(col), justify="right")
    for row in data.rows:
        out.add_row(*(escape(cell) for cell in row))
    return out


def sections(parts: list[str | TableData]) -> None:
    """A report's lines and tables, in order, on standard output (text as it is, no markup)."""
    for part in parts:
        if isinstance(part, TableData):
            stdout.print(table(part))
        else:
            stdout.print(part, soft_wrap=True, markup=False)


def _law_text(law: dict[str, Any]) -> str:
    params = ", ".join(f"{k}={fmt(v)}" for k, v in law.items() if k != "law")
    return f"{law['law']}({params})"


def _imported(record: dict[str, Any], body: dict[str, Any]) -> None:
    """What an imported data set's summary says of its measurements."""
    stdout.print(
        f"imported from {record['source'] or '?'}: {record['rows']} rows, {record['dropped_rows']} "
        f"dropped (missing values), {record['trajectories']} trajectories; sample step median "
        f"{fmt(record['step_median'])} s (range {fmt(record['step_range'][0])} – "
        f"{fmt(record['step_range'][1])} s)"
        + (f"; times read as seconds after {record['time_origin']}" if record.get("time_origin") else ""),
        soft_wrap=True,
        highlight=False,
    )
    if record.get("gaps_split"):
        limit = (
            f"{fmt(record['gap_steps'])}x the trajectory's median step"
            if record["max_gap"] is None
            else f"{fmt(record['max_gap'])} s"
        )
        stdout.print(
            f"gaps: {record['gaps_split']} gap(s) longer than {limit} split {record['tracks_split']} of "
            f"the table's {record['tracks']} trajectories into pieces named ID#1, ID#2, ...; "
            f"{record['short_pieces_dropped']} piece(s) under 3 samples dropped "
            f"({record['short_piece_rows']} rows)",
            soft_wrap=True,
            highlight=False,
        )
    forcing = record.get("forcing")
    if forcing:
        how = (
            "each row held until the next (the change times kept for training and evaluation)"
            if forcing["hold"] == "previous"
            else "interpolated at the samples"
        )
        stdout.print(f"forcing: {forcing['rows']} rows of a separate table, {how}", highlight=False)
    if record.get("outliers_dropped"):
        stdout.print(
            f"outliers: {record['outliers_dropped']} position(s) in {record['outlier_trajectories']} "
            f"trajectories lay more than {fmt(record['outlier_sigmas'])} noise levels from the cubic "
            "through their neighbours (a tracker's glitches?) and were dropped "
            "(--outliers off keeps them)" + _glitch_places(record),
            soft_wrap=True,
            highlight=False,
        )


def _glitch_places(record: dict[str, Any]) -> str:
    """Where the import dropped glitches: ``": trajectory 'a' at t = 3.2 s, …"`` (or nothing for
    a data set imported before the record kept them)."""
    places = record.get("outliers_at") or []
    if not places:
        return ""
    after = f" s after {record['time_origin']}" if record.get("time_origin") else " s"
    text = ", ".join(f"trajectory {traj!r} at t = {time:.6g}{after}" for traj, time in places)
    more = record["outliers_dropped"] - len(places)
    return f": {text}" + (f" and {more} more" if more > 0 else "")


def summary(info: dict[str, Any], path: str) -> None:
    """A data set's summary (:func:`fhnn.info`) as ``fhnn info`` prints it."""
    stdout.print(
        f"[bold]{path}[/bold]: scenario [bold]{info['scenario']}[/bold], seed {info['seed']}, "
        f"dt {fmt(info['dt'])} s, actuation {info['actuation']}, obs_noise {info['obs_noise']}, "
        f"written by fhnn {info['version']}"
    )
    body = info["body_params"]
    record = info["imported"]
    if record:  # a user's measurements: what was recorded, estimated, dropped
        _imported(record, body)
        vel_noise, vel_error = record["velocity_noise"], record.get("velocity_error")
        stdout.print(
            f"measured: {', '.join(info['measured'])}; "
            f"position noise seen: {fmt(record['position_noise'])} m"
            + (f", velocity noise seen: {fmt(vel_noise)} m/s" if vel_noise is not None else "")
            + (f", estimated velocities' RMS error: {fmt(vel_error)} m/s" if vel_error is not None else "")
            + f"; velocities: {record['velocity']}",
            soft_wrap=True,
            highlight=False,
        )
        stdout.print(
            f"body: M={body['M']} kg, rho={body['rho']} kg/m³, A={body['A']} m², V={fmt(body['V'])} m³"
        )
    else:
        params = ", ".join(
            f"{k}={v}" for k, v in info["scenario_params"].items() if k != "modes" and v is not None
        )
        stdout.print(f"parameters: {params}")
        if info["scenario_params"].get("modes"):
            stdout.print(f"flow perturbation: {len(info['scenario_params']['modes'])} frozen modes")
        laws = "; ".join(f"{k} {_law_text(body[k])}" for k in ("m_ax", "m_ay", "c_q", "c_l"))
        stdout.print(f"body: M={body['M']} kg, rho={body['rho']} kg/m³, A={body['A']} m²; {laws}")
    if any(info["redraws"].values()):
        stdout.print(f"redrawn trajectories (too close to the obstacle): {info['redraws']}")
    _splits(info)


def _splits(info: dict[str, Any]) -> None:
    """The summary's tables of split sizes and coverage."""
    splits = info["splits"]
    sizes = Table(title="splits", title_justify="left")
    for col in ("split", "trajectories", "samples", "longest track", "duration \\[s]"):
        sizes.add_column(col, justify="right")
    for name, s in splits.items():
        sizes.add_row(name, str(s["n_traj"]), str(s["samples"]), str(s["n_times"]), fmt(s["duration"]))
    stdout.print(sizes)
    states = "observed states" if info["imported"] else "clean states"  # no truth in observed data
    cover = Table(title=f"coverage of the {states} (min – max)", title_justify="left")
    cover.add_column("quantity")
    for name in splits:
        cover.add_column(name, justify="right", no_wrap=True)
    labels = {"r": "r \\[m]", "speed": "|v| \\[m/s]", "sigma": "σ \\[m/s]", "force": "|F_ext| \\[N]"}
    for key, label in labels.items():
        if key not in next(iter(splits.values()))["coverage"]:
            continue  # σ needs the true flow
        cells = [f"{fmt(s['coverage'][key][0])} – {fmt(s['coverage'][key][1])}" for s in splits.values()]
        cover.add_row(label, *cells)
    stdout.print(cover)
