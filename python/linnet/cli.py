"""Command-line interface: ``linnet --help``.

Commands are discovered from the ``linnet.commands`` package: a module defining ``COMMAND`` becomes a subcommand;
``bench_*`` modules become subcommands of ``linnet bench``. Usage errors print one line on stderr and exit with 2.
"""
from __future__ import annotations

import importlib
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


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
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
    sys.exit(rv if isinstance(rv, int) else 0)


if __name__ == "__main__":
    main()
