"""``linnet sim``: simulator tools. ``fit-imu`` fits a measured IMU noise model to a real IMU log and its ground
truth; ``check-imu`` compares a replay's IMU error spectra with a real log's (see linnet.sim.imu_model)."""
from __future__ import annotations

from pathlib import Path

import click

from linnet.commands.params import OUTPUT_FILE


def _fail(e: Exception):
    raise click.ClickException(str(e)) from None


def _print_model(model) -> None:
    from rich.console import Console
    from rich.table import Table

    from linnet.sim.imu_model import AXES, PHASES

    table = Table(title=f"IMU error model: {model.source}", title_justify="left")
    table.add_column("phase")
    table.add_column("seconds", justify="right")
    for ax in AXES:
        table.add_column(f"{ax} std", justify="right")
    for ph in PHASES:
        table.add_row(ph, f"{model.seconds[ph]:.1f}", *[f"{v:.4g}" for v in model.std[ph]])
    Console(highlight=False, markup=False).print(table)


@click.group("sim")
def sim_group():
    """Simulator tools: fit and check measured IMU noise models."""


@sim_group.command("fit-imu")
@click.argument("imu_csv", type=click.Path(dir_okay=False))
@click.argument("gt_csv", type=click.Path(dir_okay=False))
@click.option("--out", "out_file", required=True, type=OUTPUT_FILE,
              help="Model YAML to write (use it with linnet simulate --imu-noise FILE).")
@click.option("--plot", "plot_file", type=OUTPUT_FILE, default=None, help="Also plot the spectra (PNG).")
def fit_imu_command(imu_csv, gt_csv, out_file, plot_file):
    """Fit the IMU error spectra (rest / flight, per axis) of IMU_CSV (EuRoC imu0/data.csv) against GT_CSV (17-column
    EuRoC ground truth with velocities and biases)."""
    from linnet.sim.imu_model import fit_files
    from linnet.sim.trajectory import InputError

    try:
        model = fit_files(imu_csv, gt_csv)
    except InputError as e:
        _fail(e)
    try:
        model.save(out_file)
    except OSError as e:
        _fail(f"cannot write {out_file}: {e.strerror}")
    _print_model(model)
    click.echo(f"wrote {out_file}")
    if plot_file:
        from linnet.plots import plot_imu_spectra

        click.echo(f"wrote {plot_imu_spectra({'fitted': model}, plot_file)}")


@sim_group.command("check-imu")
@click.argument("imu_csv", type=click.Path(dir_okay=False))
@click.argument("gt_csv", type=click.Path(dir_okay=False))
@click.argument("dataset", type=click.Path(file_okay=False))
@click.option("--max-db", type=float, default=3.0, show_default=True, help="Largest band level difference, dB.")
@click.option("--max-std", type=float, default=0.2, show_default=True,
              help="Largest relative standard deviation difference.")
@click.option("--plot", "plot_file", type=OUTPUT_FILE, default=None, help="Plot both spectra (PNG).")
@click.option("--json", "json_file", type=OUTPUT_FILE, default=None, help="Write the figures as JSON.")
def check_imu_command(imu_csv, gt_csv, dataset, max_db, max_std, plot_file, json_file):
    """Compare the IMU error spectra of a replay (DATASET, from linnet simulate) with those of a real log (IMU_CSV
    against GT_CSV), in 9 bands from 1 to 90 Hz per axis and phase. Exit code 1 when a figure is out of bounds."""
    from rich.console import Console
    from rich.table import Table

    from linnet.sim.imu_model import AXES, PHASES, compare_models, fit_files
    from linnet.sim.trajectory import InputError

    mav0 = Path(dataset) / "mav0"
    try:
        real = fit_files(imu_csv, gt_csv)
        replay = fit_files(mav0 / "imu0" / "data.csv", mav0 / "state_groundtruth_estimate0" / "data.csv")
    except InputError as e:
        _fail(e)
    report = compare_models(real, replay)
    ok = True
    console = Console(highlight=False, markup=False, width=max(132, Console().width))
    bands = report["bands_hz"]
    for ph in PHASES:
        r = report["phases"][ph]
        table = Table(title=f"{ph}: replay / real, dB per band ({r['seconds'][0]:.1f} s real, "
                            f"{r['seconds'][1]:.1f} s replay)", title_justify="left")
        table.add_column("axis")
        for lo, hi in zip(bands[:-1], bands[1:]):
            table.add_column(f"{lo:.3g}-{hi:.3g}", justify="right")
        table.add_column("std real", justify="right")
        table.add_column("std replay", justify="right")
        for i, ax in enumerate(AXES):
            table.add_row(ax, *[f"{v:+.1f}" for v in r["db"][i]], f"{r['std_full_reference'][i]:.4g}",
                          f"{r['std_full_other'][i]:.4g}")
        console.print(table)
        console.print("std: over the whole spectrum (0 Hz to Nyquist); the bound applies to it and to the std in "
                      f"{bands[0]:g}-{bands[-1]:g} Hz")
        worst_std = max(abs(x - 1.0) for x in r["std_ratio"] + r["std_full_ratio"])
        band_ok, std_ok = r["max_abs_db"] <= max_db, worst_std <= max_std
        ok = ok and band_ok and std_ok
        console.print(f"{ph}: largest band difference {r['max_abs_db']:.1f} dB (bound {max_db:g}): "
                      f"{'ok' if band_ok else 'OUT'}; largest std difference {100 * worst_std:.0f} % (bound "
                      f"{100 * max_std:.0f} %): {'ok' if std_ok else 'OUT'}")
    report["pass"] = ok
    if json_file:
        from linnet.evaluation import InputError as WriteError, write_json_file

        try:
            write_json_file(Path(json_file), report)
        except WriteError as e:
            _fail(e)
    if plot_file:
        from linnet.plots import plot_imu_spectra

        click.echo(f"wrote {plot_imu_spectra({'real': real, 'replay': replay}, plot_file)}")
    return 0 if ok else 1


COMMAND = sim_group
