"""The ``roughslip`` command line: each command parses, loads, calls one library function.

Exit codes: 0 ok, 1 failure (I/O, numerical), 2 usage or configuration error (and an output
file that another run is writing), 3 a solve missed its tolerance in strict mode; a run stopped
by a signal gives 128 + its number: 130 SIGINT (Ctrl-C), 143 SIGTERM, 129 SIGHUP.
"""

from __future__ import annotations

import contextlib
import functools
import signal
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from roughslip._version import __version__
from roughslip.errors import RoughslipError, VerificationError
from roughslip.run.signals import exit_code, interruptible, resume_command, signal_of


def _fail(message: str, code: int) -> None:
    click.echo(f"roughslip: error: {message}", err=True)
    sys.exit(code)


def _verbose() -> bool:
    """``roughslip --verbose``: errors also print the library's detail."""
    ctx = click.get_current_context(silent=True)
    return bool(ctx and ctx.find_root().params.get("verbose"))


def handle_errors(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Turn roughslip errors into one line on stderr and the documented exit code."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except RoughslipError as exc:
            if exc.__cause__ is not None and _verbose():
                import traceback

                click.echo("".join(traceback.format_exception(exc.__cause__)).rstrip(),
                           err=True)
            _fail(str(exc), exc.exit_code)
        except KeyboardInterrupt as exc:
            click.echo("roughslip: interrupted", err=True)
            sys.exit(exit_code(signal_of(exc)))

    return wrapper


set_option = click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY=VALUE",
    help="Override a config value (inline TOML), e.g. --set surface.hurst=0.6. Repeatable.",
)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(
    __version__, "--version", prog_name="roughslip",
    message="%(prog)s %(version)s (BSD 3-Clause)\nTo cite: CITATION.cff of this version with "
            "the version number, and the 2003 report whose model it implements (docs: Licence "
            "and citation).")
@click.option("-v", "--verbose", is_flag=True,
              help="On an error, also print the library's detail (the underlying exception "
                   "and its traceback) above the one-line message.")
def cli(verbose: bool) -> None:
    """Static friction of rough elastic surfaces: squeeze, pull, slip."""


@cli.command("show-config")
@click.argument("config", type=click.Path(dir_okay=False))
@set_option
@handle_errors
def show_config(config: str, overrides: tuple[str, ...]) -> None:
    """Print CONFIG, with overrides merged and defaults filled, as TOML."""
    from roughslip.run.config import load_config

    click.echo(load_config(config, overrides).to_toml(), nl=False)


class _Progress:
    """Turns run events into a tqdm bar (terminal) or log lines (otherwise): one when the
    first solve is done (after the set-up), one per quarter of the work (at least a second
    apart), one at least every ``every`` seconds, and one at the last solve, so that a short
    run shows its progress and a long one does not flood its log."""

    def __init__(self, quiet: bool, every: float = 10.0):
        self.quiet = quiet
        self.tty = sys.stderr.isatty()
        self.every = every
        self.bar = None
        self.done = 0
        self.total = 0
        self.t0 = time.monotonic()
        self.last = 0.0
        self.first: float | None = None  # time of the first finished solve

    def eta(self, now: float) -> str:
        """Remaining time from the rate since the first finished solve (set-up excluded);
        empty until at least 3 solves and 5 % of the work have followed that one."""
        if self.first is None or self.done >= self.total:
            return ""
        since = self.done - 1
        if since < max(3, 0.05 * self.total) or now <= self.first:
            return ""
        return f", ETA {(now - self.first) / since * (self.total - self.done):.0f} s"

    def _due(self, now: float) -> bool:
        """Whether a log line is due at this solve (class docstring)."""
        if self.done in (1, self.total) or now - self.last >= self.every:
            return True
        quarter = max(1, self.total // 4)
        return self.done % quarter == 0 and now - self.last >= min(1.0, self.every)

    def __call__(self, e: dict[str, Any]) -> None:
        kind = e["kind"]
        if kind == "start":
            self.total = e["total"]
            if e.get("notes") and not self.quiet:
                for note in e["notes"]:
                    click.echo(f"roughslip: note: {note}", err=True)
            if e["skipped"] and not self.quiet:
                click.echo(f"roughslip: resuming: {e['skipped']} sample(s) already complete",
                           err=True)
            if self.tty and not self.quiet:
                from tqdm import tqdm

                self.bar = tqdm(total=self.total, unit="solve", file=sys.stderr,
                                desc=f"{e['samples']} samples x {e['depths']} depths")
        elif kind == "depth":
            self.done += 1
            now = time.monotonic()
            if self.first is None:
                self.first = now
            if self.bar is not None:
                self.bar.update(1)
            elif not self.quiet and self._due(now):
                self.last = now
                click.echo(f"roughslip: {self.done}/{self.total} solves (sample {e['sample']}, "
                           f"depth {e['depth_index']}), {now - self.t0:.0f} s elapsed"
                           f"{self.eta(now)}", err=True)
        elif kind == "done" and self.bar is not None:
            self.bar.close()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


@cli.command("run")
@click.argument("config", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", type=click.Path(dir_okay=False),
              help="HDF5 output (default: results/<config name>.h5).")
@set_option
@click.option("--workers", type=click.IntRange(min=1), help="Worker processes.")
@click.option("--resume", is_flag=True, help="Continue an existing output file.")
@click.option("--overwrite", is_flag=True, help="Replace an existing output file.")
@click.option("--scheduler", metavar="ADDRESS", help="Dask scheduler (tcp://host:port).")
@click.option("--strict", is_flag=True, help="A solve that misses its tolerance stops the run.")
@click.option("--quiet", is_flag=True, help="No progress output.")
@handle_errors
def run_cmd(config, out, overrides, workers, resume, overwrite, scheduler, strict, quiet):
    """Squeeze (and pull) every sample at every depth of CONFIG; write an HDF5 file."""
    from roughslip.run.budget import check_budget
    from roughslip.run.config import load_config
    from roughslip.run.executor import run
    from roughslip.run.partial import kept_text

    extra = ["execution.strict=true"] if strict else []
    cfg = load_config(config, [*overrides, *extra])
    if not (scheduler or cfg.execution.scheduler):  # a cluster's workers have their own
        check_budget(cfg, workers or cfg.execution.workers)  # before any surface is made
    out = out or str(Path("results") / (Path(config).stem + ".h5"))
    progress = _Progress(quiet)
    try:
        with interruptible(progress) as emit:
            summary = run(cfg, out, workers=workers, resume=resume, overwrite=overwrite,
                          scheduler=scheduler, progress=emit)
    except KeyboardInterrupt as exc:  # Ctrl-C, SIGTERM, SIGHUP: what the run finished is kept
        signum = signal_of(exc)
        again = resume_command(config, out, overrides, workers=workers, scheduler=scheduler,
                               strict=strict, quiet=quiet)
        with contextlib.suppress(OSError):  # after SIGHUP there may be no terminal to write to
            click.echo(f"roughslip: interrupted ({signal.Signals(signum).name}); "
                       f"{kept_text(out)} are kept; continue with: {again}", err=True)
        sys.exit(exit_code(signum))
    finally:
        progress.close()
    if not quiet:
        click.echo(f"roughslip: wrote {summary.path} ({summary.computed} sample(s) computed, "
                   f"{summary.skipped} kept, {summary.seconds:.1f} s)", err=True)


@cli.command("inspect")
@click.argument("path", type=click.Path(dir_okay=False))
@handle_errors
def inspect_cmd(path: str) -> None:
    """Summarise a run file: config, samples done, per-depth means, convergence."""
    from roughslip.analysis.summary import summarize

    click.echo(summarize(path))


@cli.command("fit")
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--x", "xname", default="normal_force", show_default=True,
              help="Abscissa: depth, depth_length, normal_force, contact_area, ...")
@click.option("--y", "yname", default="friction_force", show_default=True, help="Ordinate.")
@click.option("--range", "xrange", nargs=2, type=float, metavar="XMIN XMAX",
              help="Fit only depths whose mean x lies in [XMIN, XMAX].")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Also write a log-log plot (needs the plot extra).")
@handle_errors
def fit_cmd(files, xname, yname, xrange, as_json, plot_path):
    """Fit y = c x^alpha over the ensemble means of each run file (one row per file)."""
    import json

    from roughslip.analysis.fit import fit_files, format_table

    lo, hi = xrange or (None, None)
    fits = fit_files(list(files), xname, yname, xmin=lo, xmax=hi)
    if as_json:
        click.echo(json.dumps([{"file": f.path, "x": xname, "y": yname, **f.varied,
                                **f.fit.as_dict()} for f in fits], indent=1))
    else:
        click.echo(format_table(fits, xname, yname))
    if plot_path:
        from roughslip.analysis.plotting import plot_fits

        click.echo(str(plot_fits(list(files), fits, xname, yname, plot_path)))


@cli.command("topography")
@click.argument("path", required=False, type=click.Path(dir_okay=False))
@click.option("--key", help="Channel (instrument files), array (.npz) or dataset (HDF5).")
@click.option("--unit", type=click.Choice(["m", "mm", "um", "nm", "pm"]),
              help="Unit of a file that carries none (for the labels).")
@click.option("--pixel-size", type=click.FloatRange(min=0, min_open=True),
              help="Pixel size of a file that carries none, in --unit.")
@click.option("--sample", type=int, help="Run files: the sample whose surface to describe.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Also draw the height map and the PSD with its fit (needs the plot extra).")
@click.option("--formats", "list_formats", is_flag=True,
              help="List the file formats that can be read, and exit.")
@handle_errors
def topography_cmd(path, key, unit, pixel_size, sample, as_json, plot_path, list_formats):
    """What to check in a topography (or a run file's surface) before a run: format, shape,
    pixel size and unit, missing points, rms height, slope and curvature, Hurst exponent."""
    import json

    from roughslip.analysis.topography_report import describe, format_stats, plot_stats
    from roughslip.surfaces.topography import formats

    if list_formats:
        for name, exts in formats() or [("(instrument formats need the topography extra: "
                                          "pip install 'roughslip[topography]')", "")]:
            click.echo(f"{name}: {exts}" if exts else name)
        return
    if path is None:
        raise click.UsageError("missing argument PATH")
    st, h = describe(path, key=key, unit=unit, sample=sample, pixel=pixel_size)
    click.echo(json.dumps(st.as_dict(), indent=1) if as_json else format_stats(st))
    if plot_path:
        click.echo(str(plot_stats(st, h, plot_path)))


@cli.command("bursts")
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--min-tail", type=click.IntRange(min=10), default=50, show_default=True,
              help="Fewest bursts a fit range may hold.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Also plot the distributions with their fits (needs the plot extra).")
@handle_errors
def bursts_cmd(files, min_tail, as_json, plot_path):
    """Burst sizes and force drops of the pulls in FILES: distributions and power laws."""
    import json

    from roughslip.analysis.bursts import burst_report, format_table

    sample, fits = burst_report(list(files), min_tail=min_tail)
    if as_json:
        click.echo(json.dumps({"files": sample.files, "pulls": sample.pulls,
                               "left_out": sample.left_out,
                               "fits": [f.as_dict() for f in fits]}, indent=1))
    else:
        click.echo(format_table(sample, fits))
    if plot_path:
        from roughslip.analysis.plotting import plot_bursts

        click.echo(str(plot_bursts(sample, fits, plot_path)))


@cli.command("verify")
@click.option("--quick", is_flag=True,
              help="Small sizes (about half a minute on 2 cores).")
@click.option("--json", "as_json", is_flag=True,
              help="Print JSON (the points of the diagrams and the checks of the estimates).")
@click.option("--plot", "plot_path", type=click.Path(),
              help="Write the work-precision diagrams: one PNG per scene into this folder, or "
                   "one grid if it ends in .png, .pdf or .svg (needs the plot extra).")
@click.option("--quiet", is_flag=True, help="No progress lines.")
@handle_errors
def verify_cmd(quick, as_json, plot_path, quiet):
    """Errors against exact solutions and run times (work-precision), and every error estimate
    against the true error. Exits with 1 when an estimate breaks the relation it claims."""
    from roughslip.analysis import verify

    def say(msg: str) -> None:
        if not quiet:
            click.echo(f"roughslip: verify: {msg}", err=True)

    if plot_path:  # a folder that cannot be written is found before the study runs
        verify.prepare_plot(plot_path)
    result = verify.study(quick=quick, progress=say)
    click.echo(verify.to_json(result) if as_json else verify.format_table(result))
    if plot_path:
        for p in verify.plot(result, plot_path):
            say(f"wrote {p}")
    broken = [c for c in result.checks if c.holds is False]
    if broken:
        c = broken[0]
        raise VerificationError(f"verify: {len(broken)} estimate(s) break their claim, e.g. "
                             f"{c.name} ({c.kind}) of {c.scene} {c.method} {c.resolution} "
                             f"tol {c.tol:g}: {c.estimate:.2e} against {c.error:.2e}")


@cli.command("plot")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", help="Output prefix (default: the run file's name).")
@click.option("--sample", type=int, help="Sample for the maps and the pull curve.")
@click.option("--depth-index", type=int,
              help="Depth index for the maps and the pull curve (default: the deepest).")
@click.option("--solves", is_flag=True,
              help="Also plot the solves per depth: residuals, errors, iterations, seconds.")
@handle_errors
def plot_cmd(path, out, sample, depth_index, solves):
    """Friction law, F_n(D_z), contact/stick maps and a pull curve as PNG files."""
    from roughslip.analysis.plotting import plot_run

    for p in plot_run(path, out, sample, depth_index, solves=solves):
        click.echo(str(p))


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="roughslip")
