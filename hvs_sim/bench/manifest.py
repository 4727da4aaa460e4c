"""The results manifest: every headline folder, the one command that makes it, and `hvs-sim results make`.

experiments/results/MANIFEST.toml lists each cited result (name, folder, command, split, what it supports). `results
make NAME…` runs their commands from a clean checkout and writes MADE.json into each folder: the commit at the start
and at the end, whether the tree was clean at both, and `moved` when it changed under the run. Only code writes
MADE.json; `results check` (bench/headlines.py) refuses to cite a folder whose MADE.json is missing, dirty or moved.
"""

from __future__ import annotations

import json
import shlex
import shutil
import subprocess
import sys
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

from hvs_sim.errors import ConfigError, StateError
from hvs_sim.outputs import write_atomic

MANIFEST = Path("experiments/results/MANIFEST.toml")
RESULTS_ROOT = Path("experiments/results")
MADE = "MADE.json"  # written into every folder `results make` made
MADE_SCHEMA = "hvs_sim.made/1"
FOLDER_TOKEN = "{folder}"  # a command's output folder, filled in from the entry's `folder`
SPLITS = ("test", "fresh", "dev", "none")  # an entry's seeds: a split, a fresh draw, or no seeds (timings)


@dataclass(frozen=True)
class Entry:
    name: str
    folder: Path
    command: str  # `hvs-sim …` or `python experiments/….py …`, with {folder}
    split: str
    supports: str  # which published figures it backs

    def argv(self) -> list[str]:
        """The command as this interpreter runs it (the venv's hvs-sim through `-m hvs_sim.cli`)."""
        words = shlex.split(self.command.replace(FOLDER_TOKEN, str(self.folder)))
        if words[0] == "hvs-sim":
            return [sys.executable, "-m", "hvs_sim.cli", *words[1:]]
        if words[0] == "python":
            return [sys.executable, *words[1:]]
        raise ConfigError(f"manifest entry {self.name}: a command starts with hvs-sim or python, got {words[0]!r}")


def repo_root() -> Path:
    """The checkout hvs_sim runs from (the manifest's paths are relative to it)."""
    return Path(__file__).resolve().parents[2]


def load_manifest(root: Path | None = None) -> dict[str, Entry]:
    root = root or repo_root()
    path = root / MANIFEST
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"cannot read the results manifest {path} ({exc})") from None
    entries = {}
    for i, raw in enumerate(data.get("result", [])):
        missing = {"name", "folder", "command", "split", "supports"} - set(raw)
        if missing:
            raise ConfigError(f"{path}: result #{i + 1} lacks {', '.join(sorted(missing))}")
        e = Entry(raw["name"], Path(raw["folder"]), raw["command"], raw["split"], raw["supports"])
        if e.split not in SPLITS:
            raise ConfigError(f"{path}: result {e.name}: split {e.split!r}; accepted: {', '.join(SPLITS)}")
        if RESULTS_ROOT not in e.folder.parents:
            raise ConfigError(f"{path}: result {e.name}: its folder {e.folder} is not under {RESULTS_ROOT}/")
        if e.name in entries:
            raise ConfigError(f"{path}: result {e.name} is listed twice")
        if FOLDER_TOKEN not in e.command:
            raise ConfigError(f"{path}: result {e.name}: its command does not write to {FOLDER_TOKEN}")
        e.argv()  # checks the command's first word
        entries[e.name] = e
    return entries


def _git(root: Path, *args) -> str:
    try:  # only the line ends stripped: `status --porcelain` lines begin with a meaningful space
        return subprocess.run(["git", *args], capture_output=True, text=True, check=True, cwd=root).stdout.rstrip("\n")
    except (OSError, subprocess.CalledProcessError) as exc:
        raise StateError(f"`results make` needs hvs_sim's git checkout ({root}): git {' '.join(args)} failed "
                         f"({getattr(exc, 'stderr', '') or exc})") from None


def tree_state(root: Path) -> dict:
    """The commit and whether anything but experiments/results/ (what results commands write) differs from it."""
    status = _git(root, "status", "--porcelain", "--untracked-files=all")
    changed = [line[3:] for line in status.splitlines() if not line[3:].startswith(f"{RESULTS_ROOT}/")]
    return {"commit": _git(root, "rev-parse", "HEAD").strip(), "clean": not changed, "changed": changed[:20]}


def make(names: list[str], root: Path | None = None, allow_dirty: bool = False) -> list[dict]:
    """Run the named entries' commands (all when none is named), each into a fresh folder, and write their MADE.json.
    A dirty tree is refused: a result must name the code it came from."""
    root = root or repo_root()
    entries = load_manifest(root)
    unknown = [n for n in names if n not in entries]
    if unknown:
        raise ConfigError(f"not in {MANIFEST}: {', '.join(unknown)}; listed: {', '.join(entries)}")
    chosen = [entries[n] for n in names] if names else list(entries.values())
    made = []
    for e in chosen:
        start = tree_state(root)
        if not start["clean"] and not allow_dirty:
            raise StateError(f"the checkout has uncommitted changes ({', '.join(start['changed'][:5])}): commit them "
                             "first, so that the results name the code they came from")
        folder = root / e.folder
        if folder.exists():  # a manifest folder is hvs_sim's own: made again from nothing
            shutil.rmtree(folder)
        folder.mkdir(parents=True)  # empty: a benchmark's --out takes it, a script writes into it
        print(f"[results make] {e.name}: {e.command.replace(FOLDER_TOKEN, str(e.folder))}", flush=True)
        t0, started = time.perf_counter(), time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        rc = subprocess.run(e.argv(), check=False, cwd=root).returncode
        end = tree_state(root)
        record = {"schema": MADE_SCHEMA, "name": e.name, "command": e.command.replace(FOLDER_TOKEN, str(e.folder)),
                  "split": e.split, "supports": e.supports, "returncode": rc, "started_utc": started,
                  "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                  "seconds": round(time.perf_counter() - t0, 1), "commit_start": start["commit"],
                  "commit_end": end["commit"], "clean_start": start["clean"], "clean_end": end["clean"],
                  "moved": start["commit"] != end["commit"] or not (start["clean"] and end["clean"])}
        write_atomic(folder / MADE, json.dumps(record, indent=2) + "\n")
        made.append(record)
        if rc != 0:
            raise StateError(f"{e.name}: its command ended with status {rc}; {folder / MADE} records it")
        print(f"[results make] {e.name}: done in {record['seconds']:.0f} s at {start['commit'][:7]}"
              + (" (the tree moved during the run: not citable)" if record["moved"] else ""), flush=True)
    return made


def read_made(folder: Path) -> dict:
    path = folder / MADE
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ConfigError(f"{path} cannot be read ({exc}); make the folder with `hvs-sim results make`") from None
    if data.get("schema") != MADE_SCHEMA:
        raise ConfigError(f"{path} is not a {MADE_SCHEMA} record")
    return data
