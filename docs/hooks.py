"""mkdocs hook: the generated parts of the site, made at build time from the code and the result
files, never written by hand: the command reference from the Typer app (``<!-- cli-reference -->``),
the reproduction's cells from ``docs/reproduction/tables.json`` (``<!-- reproduction-cells -->``)
and the list of benchmark result files with their commits (``<!-- benchmark-results -->``)."""

from __future__ import annotations

MARK = "<!-- cli-reference -->"


def cli_reference() -> str:
    """Every command's help as Markdown: one section per command, its usage and options."""
    import click
    import typer

    from fhnn.cli.app import app

    group = typer.main.get_command(app)
    ctx = click.Context(group, info_name="fhnn", terminal_width=100, max_content_width=100)
    out = ["```text", group.get_help(ctx), "```", ""]
    for name in group.list_commands(ctx):  # type: ignore[attr-defined]
        command = group.get_command(ctx, name)  # type: ignore[attr-defined]
        sub = click.Context(command, info_name=f"fhnn {name}", parent=ctx, max_content_width=100)
        out += [f"## fhnn {name}", "", "```text", command.get_help(sub), "```", ""]
        for part in getattr(command, "list_commands", lambda _: [])(sub):  # a group's commands
            inner = command.get_command(sub, part)
            deeper = click.Context(inner, info_name=f"fhnn {name} {part}", parent=sub, max_content_width=100)
            out += [f"### fhnn {name} {part}", "", "```text", inner.get_help(deeper), "```", ""]
    return "\n".join(out)


def on_page_markdown(markdown: str, page, config, files) -> str:
    """Fill the generated parts of a page."""
    import json
    from pathlib import Path

    root = Path(config["docs_dir"]).parent
    if MARK in markdown:
        markdown = markdown.replace(MARK, cli_reference())
    if REPRODUCTION_MARK in markdown:
        markdown = markdown.replace(REPRODUCTION_MARK, reproduction_cells(root))
    if RESULTS_MARK in markdown:
        markdown = markdown.replace(RESULTS_MARK, benchmark_results(root))
    if RECOVERY_MARK in markdown:
        markdown = markdown.replace(RECOVERY_MARK, reproduction_recovery(root))
    if HEADLINE_MARK in markdown:
        cells = json.loads((root / "docs" / "reproduction" / "tables.json").read_text())["cells"]
        tables = _tables(root)
        markdown = markdown.replace(
            HEADLINE_MARK, tables.headline(cells) + "\n\n" + tables.scenario_line(cells)
        )
    if "<!-- benchmark: " in markdown or "<!-- design-data: " in markdown:
        markdown = _benchmark_sections(markdown, root)
    if TIMING_MARK in markdown:
        markdown = markdown.replace(TIMING_MARK, reproduction_timing(root))
    return markdown


REPRODUCTION_MARK = "<!-- reproduction-cells -->"
HEADLINE_MARK = "<!-- headline -->"
RESULTS_MARK = "<!-- benchmark-results -->"
RECOVERY_MARK = "<!-- reproduction-recovery -->"
TIMING_MARK = "<!-- reproduction-timing -->"


def _number(value: float | None) -> str:
    return "—" if value is None else f"{value:.3g}"


def reproduction_cells(root) -> str:
    """The reproduction's RMSE(pos) cells from ``docs/reproduction/tables.json`` beside the
    paper's: ours (mean ± std over seeds, or the median where a seed diverged), the paper's, and
    the paper's over ours."""
    import json

    records = json.loads((root / "docs" / "reproduction" / "tables.json").read_text())["cells"]
    lines = [
        "| table | data | model | horizon [s] | ours [m] | paper [m] | paper / ours |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: |",
    ]
    for r in records:
        if r["metric"] != "rmse_pos":
            continue
        if r["statistic"] == "mean":
            ours = f"{_number(r['mean'])} ± {r['std']:.2g}"
        elif r["mean"] is None:
            ours = f"diverged ({r['diverged']}/{r['rollouts']} rollouts)"
        else:
            ours = f"median {_number(r['mean'])} ({r['diverged']}/{r['rollouts']} diverged)"
        ratio = "" if not r.get("paper") or not r["mean"] else f"{r['paper'] / r['mean']:.3g}×"
        cells = [r["table"], r["data"], r["model"], f"{r['horizon']:g}", ours, _number(r.get("paper")), ratio]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def benchmark_results(root) -> str:
    """Every ``benchmarks/results/*.json`` with the commit that made it."""
    import json

    lines = [
        "| result file | made at commit | source digest | machine | date |",
        "| --- | --- | --- | --- | --- |",
    ]
    for path in sorted((root / "benchmarks" / "results").glob("*.json")):
        record = json.loads(path.read_text())
        commit = record.get("commit", "not recorded")
        made = record.get("provenance") or {}
        machine = made.get("machine") or {}
        cells = [
            f"`benchmarks/results/{path.name}`",
            f"`{commit[:12]}{'+dirty' if 'dirty' in commit else ''}`",
            f"`{made['source']}`" if made else "not recorded",
            f"{machine.get('cpu', '')}, {machine.get('cores', '?')} cores" if machine else "",
            made.get("date", "")[:10],
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def reproduction_recovery(root) -> str:
    """T6 of ``docs/reproduction/tables.json``: each data set's largest relative error [%] of the
    added masses, drag coefficients and flow over the data's range, mean ± std over the seeds."""
    import json

    records = json.loads((root / "docs" / "reproduction" / "tables.json").read_text())["cells"]
    metrics = ("m_ax", "m_ay", "c_l", "c_q", "flow")
    cells: dict[str, dict[str, str]] = {}
    for r in records:
        if r["table"] == "T6" and r["metric"] in metrics and r["mean"] is not None:
            text = f"{100 * r['mean']:.2g} ± {100 * r['std']:.2g}"
            if r["diverged"]:  # seeds whose value is not finite, left out of the mean
                text += f" ({r['diverged']}/{r['rollouts']} seeds non-finite)"
            cells.setdefault(r["data"], {})[r["metric"]] = text
    lines = ["| data | " + " | ".join(metrics) + " |", "| --- |" + " ---: |" * len(metrics)]
    for data, row in cells.items():
        lines.append(f"| {data} | " + " | ".join(row.get(m, "—") for m in metrics) + " |")
    return "\n".join(lines)


def reproduction_timing(root) -> str:
    """One sentence from ``docs/reproduction/timings.json``: jobs, wall clock, CPU time."""
    import json

    t = json.loads((root / "docs" / "reproduction" / "timings.json").read_text())
    wall = t.get("wall_seconds_this_run")
    minutes = "" if wall is None else f"{int(wall // 60)} min {int(wall % 60)} s of wall clock, "
    return (
        f"{t['jobs']} jobs: {minutes}{t['job_seconds_total'] / 60:.0f} CPU-minutes of jobs "
        "(`docs/reproduction/timings.json`)."
    )


def _tables(root):
    """``benchmarks/tables.py``, which renders the result files."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("benchmark_tables", root / "benchmarks" / "tables.py")
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    return tables


def _benchmark_sections(markdown: str, root) -> str:
    """Each ``<!-- benchmark: NAME -->`` replaced by ``benchmarks/tables.py``'s rendering of
    ``benchmarks/results/NAME.json``, each ``<!-- design-data: NAME -->`` by that of
    ``docs/design/data/NAME.json`` (the record of a choice); a missing file fails the build."""
    import json
    import re

    tables = _tables(root)

    def one(match: re.Match) -> str:
        name = match.group(1)
        path = root / "benchmarks" / "results" / f"{name}.json"
        if not path.is_file():
            raise FileNotFoundError(f"docs: no result file {path} for <!-- benchmark: {name} -->")
        return tables.render(name, json.loads(path.read_text()))

    def design(match: re.Match) -> str:
        name = match.group(1)
        path = root / "docs" / "design" / "data" / f"{name}.json"
        if not path.is_file():
            raise FileNotFoundError(f"docs: no design data {path} for <!-- design-data: {name} -->")
        return tables.render(name, json.loads(path.read_text()), folder="docs/design/data")

    markdown = re.sub(r"<!-- design-data: ([a-z0-9_]+) -->", design, markdown)
    return re.sub(r"<!-- benchmark: ([a-z0-9_]+) -->", one, markdown)
