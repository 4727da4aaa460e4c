"""A benchmark's or sweep's workers die with their parent, even when it is SIGKILLed (no orphans)."""

import os
import signal
import subprocess
import sys
import time

import pytest

SCRIPT = """
import sys, time
from hvs_sim.bench.pool import run_jobs

def job(path):
    import os, time
    open(path, "w").write(str(os.getpid()))
    time.sleep(120)

if __name__ == "__main__":
    list(run_jobs(job, [sys.argv[1] + "/a", sys.argv[1] + "/b"], 2, "test", "job", progress=False))
"""


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split()[2] != "Z"  # a zombie is dead, waiting for its reaper
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_workers_die_within_seconds_of_a_sigkilled_parent(tmp_path):
    script = tmp_path / "parent.py"
    script.write_text(SCRIPT)
    parent = subprocess.Popen([sys.executable, str(script), str(tmp_path)])
    pids = []
    try:
        deadline = time.time() + 120
        while len(pids) < 2 and time.time() < deadline:
            pids = [int(p.read_text()) for p in (tmp_path / "a", tmp_path / "b") if p.exists() and p.read_text()]
            time.sleep(0.2)
        assert len(pids) == 2 and all(_alive(p) for p in pids)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        deadline = time.time() + 5
        while any(_alive(p) for p in pids) and time.time() < deadline:
            time.sleep(0.1)
        assert not any(_alive(p) for p in pids), pids
    finally:
        for p in pids:
            if _alive(p):
                os.kill(p, signal.SIGKILL)
        if parent.poll() is None:
            parent.kill()
