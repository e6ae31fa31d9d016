"""Command-line interface: `linnet --help`."""
import sys

import click


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
def cli():
    """Linnet: point-and-line visual-inertial SLAM."""


def main():
    try:
        cli(standalone_mode=True)
    except KeyboardInterrupt:
        sys.exit(130)
