"""Which code a result came from, read once by every writer of results (the CLI's benches, bench servo)."""

from __future__ import annotations

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
        dirty = bool(git("status", "--porcelain", "--", str(here)))  # the package's code differs from the commit
    except (OSError, subprocess.SubprocessError):
        commit, dirty = "unknown", None
    return {"hvs_sim_version": __version__, "commit": commit, "code_modified": dirty}
