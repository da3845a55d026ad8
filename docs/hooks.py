"""mkdocs hook: the command reference is generated from the Typer app at build time, never
written by hand (a page holding ``<!-- cli-reference -->`` gets every command's ``--help``)."""

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
    return "\n".join(out)


def on_page_markdown(markdown: str, page, config, files) -> str:
    if MARK in markdown:
        return markdown.replace(MARK, cli_reference())
    return markdown
