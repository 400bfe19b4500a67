"""``--scheduler`` against what a cluster can do wrong: every wait is bounded and ends in a named error that says what
to check (a port that accepts and says nothing, an HTTP server, TLS, a scheduler without workers, the last worker
lost, the scheduler killed). Each hung or crashed raw before its guard."""

from __future__ import annotations

import http.server
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from ffsr_gym import cluster
from ffsr_gym.cluster import cluster_executor, parse_scheduler
from ffsr_gym.exceptions import InvalidInputError

ROOT = Path(__file__).resolve().parents[2]
distributed = pytest.importorskip("distributed")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture()
def quick(monkeypatch):
    """Short bounds, so that a test waits seconds where a study would wait minutes."""
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 2)
    monkeypatch.setattr(cluster, "NO_WORKER_TIMEOUT_S", 3.0)
    monkeypatch.setattr(cluster, "WATCH_INTERVAL_S", 0.5)


def test_tls_is_refused_by_name():
    with pytest.raises(InvalidInputError, match="TLS needs certificates"):
        parse_scheduler("tls://127.0.0.1:8786")


def test_a_port_that_accepts_and_says_nothing_is_an_error_within_the_bound(quick):
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    held = []
    threading.Thread(target=lambda: held.extend(server.accept() for _ in range(8)), daemon=True).start()
    started = time.monotonic()
    with pytest.raises(InvalidInputError, match="no Dask scheduler answered"):
        with cluster_executor(f"127.0.0.1:{server.getsockname()[1]}", say=lambda text: None):
            pass
    assert time.monotonic() - started < 30
    server.close()


def test_an_http_server_on_the_port_is_an_error_not_an_allocation(quick):
    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args) -> None:  # the Dask handshake it refuses is expected: not logged
            pass

    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Quiet)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        with pytest.raises(InvalidInputError, match="no Dask scheduler answered"):
            with cluster_executor(f"127.0.0.1:{httpd.server_address[1]}", say=lambda text: None):
                pass
    finally:
        httpd.shutdown()


def _start(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", *args], env={**os.environ, "PYTHONPATH": str(ROOT)},
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def _stop(*processes: subprocess.Popen) -> None:
    for process in processes:
        if process.poll() is None:
            process.kill()
        process.wait(timeout=30)


def _scheduler() -> tuple[str, subprocess.Popen]:
    address = f"tcp://127.0.0.1:{_free_port()}"
    process = _start("distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", address.rsplit(":", 1)[1],
                     "--no-dashboard")
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", int(address.rsplit(":", 1)[1])), timeout=1).close()
            return address, process
        except OSError:
            time.sleep(0.2)
    raise AssertionError("the scheduler did not start")


def _worker(address: str, tmp: Path) -> subprocess.Popen:
    return _start("distributed.cli.dask_worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                  "--memory-limit", "0", "--local-directory", str(tmp))


def test_a_scheduler_without_workers_is_an_error_within_the_bound(quick):
    address, scheduler = _scheduler()
    try:
        with pytest.raises(InvalidInputError, match="no worker joined the scheduler"):
            with cluster_executor(address, say=lambda text: None):
                pass
    finally:
        _stop(scheduler)


def test_losing_the_last_worker_or_the_scheduler_fails_the_waiting_pieces_by_name(quick, tmp_path):
    address, scheduler = _scheduler()
    worker = _worker(address, tmp_path / "w1")
    try:
        with cluster_executor(address, say=lambda text: None) as (executor, slots):
            assert slots == 1 and executor.submit(sum, [1, 2]).result(timeout=60) == 3
            waiting = executor.submit(time.sleep, 600)
            time.sleep(1.0)
            worker.send_signal(signal.SIGKILL)  # the last worker: nobody left to run the piece
            with pytest.raises(InvalidInputError, match="no worker on the cluster"):
                waiting.result(timeout=60)
        worker = _worker(address, tmp_path / "w2")
        with cluster_executor(address, say=lambda text: None) as (executor, _):
            waiting = executor.submit(time.sleep, 600)
            time.sleep(1.0)
            scheduler.send_signal(signal.SIGKILL)
            with pytest.raises(InvalidInputError, match="--scheduler"):
                waiting.result(timeout=90)
    finally:
        _stop(worker, scheduler)
