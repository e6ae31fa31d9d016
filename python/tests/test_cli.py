"""CLI smoke tests: help texts, one-line usage errors with exit code 2."""
import subprocess
import sys
from pathlib import Path

import pytest

LINNET = [sys.executable, "-m", "linnet.cli"]


def _run(*args, cwd=None):
    return subprocess.run(LINNET + list(args), capture_output=True, text=True, cwd=cwd, timeout=300)


@pytest.mark.parametrize("args", [["--help"], ["run", "--help"], ["config", "--help"], ["demo", "--help"],
                                  ["bench", "--help"], ["bench", "stages", "--help"]])
def test_help(args):
    r = _run(*args)
    assert r.returncode == 0, r.stderr
    assert "Usage:" in r.stdout


@pytest.mark.parametrize("args", [["bogus"], ["run"], ["run", "/no/such/dataset"], ["run", ".", "--max-frames", "x"],
                                  ["--no-such-option"]])
def test_bad_arguments_give_one_line_and_exit_code_2(args):
    r = _run(*args)
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("linnet")


def test_config_prints_every_section():
    r = _run("config")
    assert r.returncode == 0, r.stderr
    for section in ("cam0:", "cam1:", "imu:", "points:", "lines:", "estimator:", "pipeline:"):
        assert section in r.stdout


def test_run_on_a_folder_that_is_not_euroc_fails_cleanly(tmp_path):
    r = _run("run", str(tmp_path), "--out", str(tmp_path / "out"))
    assert r.returncode != 0
    assert "Traceback" not in r.stderr
    assert "mav0" in r.stderr or str(tmp_path) in r.stderr


def test_shipped_config_loads():
    import linnet

    shipped = Path(__file__).resolve().parents[2] / "config" / "euroc_stereo_imu.yaml"
    cfg = linnet.Config.load(str(shipped))
    assert cfg.stereo


def test_stage_table_shares(tmp_path):
    from linnet.commands.bench_stages import stage_table

    header = ("#timestamp [ns],frontend_ms,backend_ms,total_ms,point_ms,line_ms,points,stereo_points,lines,keyframe,"
              "status,point_cpu_ms,line_cpu_ms,backend_cpu_ms,line_backend_ms,solver_ms,landmark_points,"
              "landmark_lines")
    rows = [f"{i},5,2,7,4,5,100,80,30,0,1,{3 + i % 2},{2},{1},0.2,0.8,90,20" for i in range(10)]
    csv = tmp_path / "timing.csv"
    csv.write_text(header + "\n" + "\n".join(rows) + "\n")
    table = stage_table(csv)
    shares = [table[k]["share"] for k in ("points_cpu", "lines_cpu", "backend_cpu")]
    assert abs(sum(shares) - 1.0) < 1e-12 and abs(shares[0] - 3.5 / 6.5) < 1e-12
    assert table["frame_cpu"]["median_ms"] == 6.5 and table["solver"]["median_ms"] == 0.8


def test_memory_growth_from_timing(tmp_path):
    from linnet.commands.bench_stages import memory_growth

    header = ("#timestamp [ns],frontend_ms,backend_ms,total_ms,point_ms,line_ms,points,stereo_points,lines,keyframe,"
              "status,point_cpu_ms,line_cpu_ms,backend_cpu_ms,line_backend_ms,solver_ms,landmark_points,"
              "landmark_lines,loop_cpu_ms,rss_mb")
    # 20 Hz for 120 s; the resident set grows by 0.1 MB per second of data from 100 MB.
    rows = [f"{i * 50_000_000},5,2,7,4,5,100,80,30,0,1,3,2,1,0.2,0.8,90,20,0,{100 + 0.1 * i * 0.05:.3f}"
            for i in range(2401)]
    csv = tmp_path / "timing.csv"
    csv.write_text(header + "\n" + "\n".join(rows) + "\n")
    m = memory_growth(csv)
    assert abs(m["rss_after_mb"] - 106.0) < 1e-9 and abs(m["rss_end_mb"] - 112.0) < 1e-9
    assert abs(m["growth"] - (112.0 / 106.0 - 1.0)) < 1e-12 and abs(m["end_s"] - 120.0) < 1e-9
    assert memory_growth(csv, after_s=500.0) is None
