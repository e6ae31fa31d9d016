"""`linnet bench suite` on Ray (issue 11): a local Ray head started here (``ray start --head`` on 127.0.0.1), a
2-job suite through ``--ray-address``, the same rows as the serial run (timings aside), and the report files."""
from __future__ import annotations

import json
import os
import shutil
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from linnet.suite import reproducible

LINNET = [sys.executable, "-m", "linnet.cli"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def ray_head():
    """A Ray head on 127.0.0.1 with 2 CPUs, in its own process group (stopped by killing that group only)."""
    pytest.importorskip("ray")
    ray_bin = Path(sys.executable).with_name("ray")
    temp = tempfile.mkdtemp(prefix="lnr", dir="/tmp")  # short: Ray's socket paths must stay under 107 characters
    port = _free_port()
    # A token of its own (Ray's token authentication), given to the head and to every driver through the
    # environment: nothing is read from or written to ~/.ray.
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0", RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=secrets.token_hex(32))
    proc = subprocess.Popen([str(ray_bin), "start", "--head", "--block", "--node-ip-address", "127.0.0.1",
                             "--port", str(port), "--num-cpus", "2", "--include-dashboard", "false",
                             "--temp-dir", temp, "--disable-usage-stats"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, start_new_session=True)
    address = f"127.0.0.1:{port}"
    deadline = time.time() + 120
    while time.time() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                break
        if proc.poll() is not None:
            pytest.fail(f"ray start exited with {proc.returncode}")
        time.sleep(0.5)
    else:
        pytest.fail("the Ray head did not come up within 120 s")
    yield address, env
    os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
    shutil.rmtree(temp, ignore_errors=True)


def test_ray_suite_gives_the_serial_rows(tmp_path, ray_head, short_loop_tum):
    tum = short_loop_tum
    oracle = ("oracle=awk -F, '!/^#/ {{printf \"%.9f %s %s %s %s %s %s %s\\n\", $1/1e9, $2+0.001*NR%3, $3, $4, $6, "
              "$7, $8, $5}}' {dataset}/mav0/state_groundtruth_estimate0/data.csv > {tum}")
    common = ["bench", "suite", "--sequences", str(tum), "--scenes", "lowtex", "--duration", "1.5", "--start", "2",
              "--systems", oracle, "--cache", str(tmp_path / "cache")]
    serial = subprocess.run(LINNET + common + ["--executor", "serial", "--runs", str(tmp_path / "runs_serial"),
                                               "--json", str(tmp_path / "serial.json")],
                            capture_output=True, text=True, timeout=900)
    assert serial.returncode == 0, serial.stderr
    # The Ray run renders its own replay (another cache) so that both jobs, render and run, go through Ray.
    address, env = ray_head
    on_ray = subprocess.run(LINNET + common[:-1] + [str(tmp_path / "cache_ray"), "--ray-address", address,
                                                    "--runs", str(tmp_path / "runs_ray"),
                                                    "--report", str(tmp_path / "report")],
                            capture_output=True, text=True, timeout=900, env=env)
    assert on_ray.returncode == 0, on_ray.stderr
    assert "executor ray" in on_ray.stderr and "2 jobs" in on_ray.stderr
    rows_serial = json.loads((tmp_path / "serial.json").read_text())
    report = json.loads((tmp_path / "report" / "suite.json").read_text())
    assert report["executor"] == "ray" and len(report["rows"]) == 1
    keep = ("dataset", "out")  # paths differ by construction
    a = [{k: v for k, v in reproducible(r).items() if k not in keep} for r in rows_serial]
    b = [{k: v for k, v in reproducible(r).items() if k not in keep} for r in report["rows"]]
    assert a == b and a[0]["ape_rmse_m"] is not None and a[0]["ape_rmse_m"] > 0
    assert (tmp_path / "report" / "suite.png").stat().st_size > 1000
    assert "| short | lowtex | oracle |" in (tmp_path / "report" / "suite.md").read_text()
    # The replays are byte-identical whichever executor rendered them.
    da, db = Path(a and rows_serial[0]["dataset"]), Path(report["rows"][0]["dataset"])
    for rel in ("mav0/imu0/data.csv", "mav0/cam0/data.csv", "mav0/state_groundtruth_estimate0/data.csv"):
        assert (da / rel).read_bytes() == (db / rel).read_bytes()
