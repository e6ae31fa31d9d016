"""`linnet bench all`: every benchmark that needs no outside data, one after the other (`make bench`)."""
from __future__ import annotations

import click


@click.command("all")
@click.pass_context
def COMMAND(ctx):
    """Stage timings on a simulated sequence, then the line front-end on the real EuRoC snippet if present."""
    from pathlib import Path

    bench = ctx.parent.command
    click.echo("== per-stage timing (simulated room sequence) ==")
    ctx.invoke(bench.get_command(ctx, "stages"))
    lines = bench.get_command(ctx, "lines")
    micro = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "euroc" / "V1_01_easy_micro"
    if lines is not None and micro.is_dir():
        click.echo("== line front-end (real EuRoC V1_01 snippet) ==")
        ctx.invoke(lines, dataset=micro)
