"""`linnet config`: print the full configuration (defaults, or a dataset's calibration + a file's overrides)."""
from __future__ import annotations

from pathlib import Path

import click

from linnet.commands.params import OUTPUT_FILE


@click.command("config")
@click.option("--dataset", type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="Take the calibration from this EuRoC folder.")
@click.option("--config", "config_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="YAML file to merge on top.")
@click.option("--out", type=OUTPUT_FILE, help="Write to this file instead of stdout.")
def COMMAND(dataset, config_file, out):
    """Print every configuration key with its value, documentation and range (YAML comments), e.g. to start a
    config file from."""
    import linnet

    try:
        cfg = linnet.Config.for_euroc(str(dataset)) if dataset else linnet.Config.euroc_stereo_imu()
        if config_file:
            cfg.merge(str(config_file))
    except linnet.Error as e:
        raise click.ClickException(str(e))
    if out:
        cfg.save(str(out))  # with every key's documentation and range as comments
    else:
        click.echo(cfg.to_yaml(comments=True), nl=False)
