"""Click parameter types shared by the commands: output folders and files checked before any work is done; and the
evaluation commands' data error and JSON report writer.

A run, a render or a plot that can only fail at the end, when it writes, loses the work; these types check, when the
command line is parsed, that the path can be created and written, without creating anything. A path that cannot is a
usage error (exit code 2) naming the option and the reason.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import click


def _first_existing(path: Path) -> Path:
    """The path itself or its nearest existing ancestor."""
    p = path.absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def writable_problem(path: Path, folder: bool) -> str:
    """Why `path` (a folder if `folder`, else a file) cannot be created / written, or "" if it can."""
    if path.exists():
        if folder and not path.is_dir():
            return "exists and is not a folder"
        if not folder and path.is_dir():
            return "is a folder, expected a file"
        target = path if folder else path.parent
        return "" if os.access(target, os.W_OK | os.X_OK) else f"{target}: permission denied"
    base = _first_existing(path.parent if not folder else path)
    if not base.is_dir():
        return f"{base} is a file, not a folder"
    if not os.access(base, os.W_OK | os.X_OK):
        return f"{base}: permission denied"
    return ""


class OutputPath(click.Path):
    """A click.Path for an output folder (`folder=True`) or file that must be creatable and writable."""

    def __init__(self, folder: bool):
        super().__init__(file_okay=not folder, dir_okay=folder, path_type=Path)
        self.folder = folder
        self.name = "folder" if folder else "file"

    def convert(self, value, param, ctx):
        path = super().convert(value, param, ctx)
        problem = writable_problem(Path(path), self.folder)
        if problem:
            self.fail(f"{path}: cannot write the output {self.name} ({problem})", param, ctx)
        return path


OUTPUT_DIR = OutputPath(folder=True)
OUTPUT_FILE = OutputPath(folder=False)


class FiniteFloat(click.FloatRange):
    """A float in a range that also refuses nan and inf (click's FloatRange lets nan through)."""

    def convert(self, value, param, ctx):
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        return number


#: Seconds >= 0 (offsets into a sequence).
SECONDS = FiniteFloat(min=0.0)
#: Seconds > 0 (durations).
POSITIVE_SECONDS = FiniteFloat(min=0.0, min_open=True)


def key_values(ctx, param, values):
    """Callback of the --set options: every value must be KEY=VALUE with a key (a usage error otherwise)."""
    for item in values:
        key, sep, _ = item.partition("=")
        if not sep or not key.strip():
            raise click.BadParameter(f"'{item}' is not KEY=VALUE (e.g. pipeline.use_lines=false)", ctx, param)
    return values


class DataError(click.ClickException):
    """Missing or malformed input data (linnet.evaluation.InputError): one line on stderr, exit code 1."""

    exit_code = 1


def write_json_report(path: Path, report: dict) -> None:
    """Writes an evaluation report as JSON (linnet.evaluation.write_json_file); a write failure is a DataError."""
    from linnet import evaluation as ev

    try:
        ev.write_json_file(path, report)
    except ev.InputError as e:
        raise DataError(str(e)) from None
