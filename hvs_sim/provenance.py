"""Which code a result came from, read once by every writer of results (the CLI's benches, bench servo)."""

from __future__ import annotations

import hashlib
import subprocess
from pathlib import Path


def code_provenance() -> dict:
    """hvs_sim's version, the commit of the checkout it runs from and whether the package's code differs from that
    commit. Outside hvs_sim's own checkout (no git, an install, a copy inside another repository) the commit is
    "unknown" and code_modified None: another repository's commit would name the wrong code."""
    from hvs_sim import __version__

    here = Path(__file__).resolve().parent  # the package's folder
    try:
        def git(*args):
            return subprocess.run(["git", *args], capture_output=True, text=True, check=True, cwd=here).stdout.strip()

        if Path(git("rev-parse", "--show-toplevel")).resolve() != here.parent:  # installed inside another repository
            raise OSError("not hvs_sim's own checkout")
        commit = git("rev-parse", "HEAD")
        status = git("status", "--porcelain", "--", str(here))
        dirty = bool(status)  # the package's code differs from the commit
        # what differs, as a digest: two reads with the same commit and other uncommitted code are told apart
        diff = hashlib.sha256((status + git("diff", "HEAD", "--", str(here))).encode()).hexdigest()[:16] if dirty else None
    except (OSError, subprocess.SubprocessError):
        commit, dirty, diff = "unknown", None, None
    return {"hvs_sim_version": __version__, "commit": commit, "code_modified": dirty, "code_diff": diff}


def moved(start: dict, end: dict) -> bool:
    """Whether the code changed between two code_provenance() reads (the commit, or its uncommitted changes)."""
    return any(start.get(k) != end.get(k) for k in ("commit", "code_modified", "code_diff"))
