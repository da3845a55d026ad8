"""The Typer application and the options several commands share."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from fhnn.runtime import __version__, default_cache_dir, use_compilation_cache


def _version(value: bool) -> None:
    if value:
        typer.echo(f"fhnn {__version__}")
        raise typer.Exit()


app = typer.Typer(
    name="fhnn",
    help="Floating-Body Hydrodynamic Neural Networks: simulate, learn and evaluate floating-body dynamics.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)


@app.callback()
def _main(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit."),
    ] = False,
) -> None:
    """Floating-Body Hydrodynamic Neural Networks: simulate, learn and evaluate floating-body dynamics.

    Compiled programs are cached in $FHNN_JAX_CACHE (default ~/.cache/fhnn/jax; "off": no cache).
    """
    use_compilation_cache(default_cache_dir())


#: ``--config FILE`` of the commands that take settings.
ConfigFileOption = Annotated[
    Path | None,
    typer.Option(
        "--config",
        help="Settings file (TOML or JSON): names and [section] tables, e.g. [train] lr = 1e-3.",
    ),
]
#: ``--quiet`` of the commands with a progress bar.
QuietOption = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")]
#: The run folder argument of evaluate and inspect.
RunDirArgument = Annotated[
    Path, typer.Argument(help="Run folder (or ensemble folder) written by `fhnn train`.")
]
#: The optional data set argument of evaluate and inspect.
DataArgument = Annotated[
    Path | None, typer.Argument(help="Data set [default: the one the run was trained on]")
]


def SetOption(example: str) -> Any:
    """The ``--set NAME=VALUE`` option type, with an example of dotted names in its help."""
    return Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            metavar="NAME=VALUE",
            help=f"A setting by dotted name, e.g. {example} (repeatable; wins over --config).",
        ),
    ]


#: ``--columns`` of ``fhnn import`` and ``fhnn predict``: the table's names of our columns.
ColumnsOption = Annotated[
    str | None,
    typer.Option(
        "--columns",
        help="The table's names of fhnn's columns where they differ, e.g. "
        "traj_id=track,t=time,x=pos_x,y=pos_y,Fx=thrust_x,Fy=thrust_y.",
    ),
]


#: ``--time-unit`` of ``fhnn import`` and ``fhnn predict``.
TimeUnitOption = Annotated[
    str,
    typer.Option(
        "--time-unit",
        help="Unit of the table's numeric times: s, ms, us, min or h (read as seconds).",
    ),
]

#: ``--forcing-hold`` of import and predict.
ForcingHoldOption = Annotated[
    str,
    typer.Option(
        "--forcing-hold",
        help="How --forcing reads between its rows: linear (interpolated) or previous (each row's "
        "force held until the next row, as thrusters that switch at the rows' times).",
    ),
]
