"""Command-line interface: ``linnet --help``.

Commands are discovered from the ``linnet.commands`` package: a module defining ``COMMAND`` becomes a subcommand;
``bench_*`` modules become subcommands of ``linnet bench``. Every error is one line on stderr (no traceback; set
LINNET_DEBUG=1 to see one), with the exit codes of EXIT_CODES.
"""
from __future__ import annotations

import importlib
import os
import pkgutil
import sys

import click

from linnet import commands as _commands_pkg


def _discover(prefix_filter):
    found = []
    for info in sorted(pkgutil.iter_modules(_commands_pkg.__path__), key=lambda i: i.name):
        if not prefix_filter(info.name):
            continue
        module = importlib.import_module(f"linnet.commands.{info.name}")
        command = getattr(module, "COMMAND", None)
        if isinstance(command, click.Command):
            found.append(command)
    return found


#: Exit codes of every command (shown by ``linnet --help``).
EXIT_CODES = {
    0: "success",
    1: "bad input data or a failed step (the message names the file, line or key)",
    2: "usage error (an unknown option, a bad option value, a path that cannot be written)",
    3: "linnet run: the run went through but did not track (outputs written, reasons printed)",
    4: "internal error (a bug: please report it with LINNET_DEBUG=1's traceback)",
    130: "interrupted",
}

_EPILOG = "\b\nExit codes:\n" + "\n".join(f"  {code:<4}{text}" for code, text in EXIT_CODES.items())


@click.group(context_settings={"help_option_names": ["-h", "--help"]}, epilog=_EPILOG)
@click.version_option(package_name="linnet")
def cli():
    """Linnet: point-and-line visual-inertial SLAM (stereo/mono + IMU)."""


@cli.group("bench")
def bench():
    """Benchmarks that print tables (and JSON): stages, line front-end, sequence suites."""


for _cmd in _discover(lambda name: not name.startswith("bench_")):
    cli.add_command(_cmd)
for _cmd in _discover(lambda name: name.startswith("bench_")):
    bench.add_command(_cmd)


def _is_data_error(e: BaseException) -> bool:
    """Linnet's own errors: the core's (linnet.Error and subclasses) and the Python package's InputError / BagError."""
    from linnet.fileio import InputError

    if isinstance(e, InputError) or type(e).__name__ == "BagError":
        return True
    return any(c.__module__ == "linnet._linnet" and c.__name__ == "Error" for c in type(e).__mro__)


def main(argv=None):
    """Entry point of the ``linnet`` script."""
    try:
        rv = cli.main(args=argv, prog_name="linnet", standalone_mode=False)
    except click.exceptions.Exit as e:
        sys.exit(e.exit_code)
    except click.exceptions.Abort:
        click.echo("linnet: aborted", err=True)
        sys.exit(130)
    except click.UsageError as e:
        where = f" {e.ctx.command_path.split(' ', 1)[1]}" if e.ctx and " " in e.ctx.command_path else ""
        click.echo(f"linnet{where}: error: {e.format_message()} (see --help)", err=True)
        sys.exit(2)
    except click.ClickException as e:
        click.echo(f"linnet: error: {e.format_message()}", err=True)
        sys.exit(e.exit_code)
    except KeyboardInterrupt:
        sys.exit(130)
    except Exception as e:  # noqa: BLE001 - the last line of defence: one line, never a traceback
        if os.environ.get("LINNET_DEBUG"):
            raise
        if _is_data_error(e):
            click.echo(f"linnet: error: {e}", err=True)
            sys.exit(1)
        click.echo(f"linnet: internal error: {type(e).__name__}: {e} (LINNET_DEBUG=1 shows the traceback)", err=True)
        sys.exit(4)
    sys.exit(rv if isinstance(rv, int) else 0)


if __name__ == "__main__":
    main()
