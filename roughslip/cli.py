"""The ``roughslip`` command line: each command parses, loads, calls one library function.

Exit codes: 0 ok, 1 failure (I/O, numerical), 2 usage or configuration error, 3 a solve missed
its tolerance in strict mode, 130 interrupted.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from typing import Any

import click

from ._version import __version__
from .errors import RoughslipError


def _fail(message: str, code: int) -> None:
    click.echo(f"roughslip: error: {message}", err=True)
    sys.exit(code)


def handle_errors(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Turn roughslip errors into one line on stderr and the documented exit code."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except RoughslipError as exc:
            _fail(str(exc), exc.exit_code)
        except KeyboardInterrupt:
            click.echo("roughslip: interrupted", err=True)
            sys.exit(130)

    return wrapper


set_option = click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY=VALUE",
    help="Override a config value (inline TOML), e.g. --set surface.hurst=0.6. Repeatable.",
)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="roughslip")
def cli() -> None:
    """Static friction of rough elastic surfaces: squeeze, pull, slip."""


@cli.command("show-config")
@click.argument("config", type=click.Path(dir_okay=False))
@set_option
@handle_errors
def show_config(config: str, overrides: tuple[str, ...]) -> None:
    """Print CONFIG, with overrides merged and defaults filled, as TOML."""
    from .config import load_config

    click.echo(load_config(config, overrides).to_toml(), nl=False)


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="roughslip")
