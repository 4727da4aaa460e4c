"""Headline results: the manifest's commands, `results make` from a clean tree only, and `results check` failing on
any figure, folder or provenance that disagrees with the records."""

import json
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest

from hvs_sim.bench import headlines, manifest
from hvs_sim.cli import build_parser
from hvs_sim.errors import ConfigError, StateError

ROOT = Path(__file__).resolve().parents[1]


def test_every_manifest_command_parses_and_writes_its_folder():
    entries = manifest.load_manifest(ROOT)
    assert entries and len({e.folder for e in entries.values()}) == len(entries)
    for e in entries.values():
        words = shlex.split(e.command.replace(manifest.FOLDER_TOKEN, str(e.folder)))
        if words[0] == "hvs-sim":
            args = build_parser().parse_args(words[1:])
            assert Path(args.out) == e.folder
        else:
            assert (ROOT / words[1]).is_file()
        if e.split == "test":
            assert "--split test" in e.command or "--seeds 3000" in e.command
        if e.split == "fresh":
            assert "--fresh" in e.command


def _git(root, *args):
    subprocess.run(["git", *args], cwd=root, check=True, capture_output=True)


@pytest.fixture
def repo(tmp_path):
    """A git checkout with a manifest of one entry whose command writes a file into its folder."""
    (tmp_path / "experiments/results").mkdir(parents=True)
    (tmp_path / "experiments/results/MANIFEST.toml").write_text(
        '[[result]]\nname = "a"\nfolder = "experiments/results/a"\n'
        'command = "python -c \\"import sys, pathlib; pathlib.Path(sys.argv[1], \'x.txt\').write_text(\'1\')\\" {folder}"\n'
        'split = "none"\nsupports = "a test"\n'
        '[[result]]\nname = "fails"\nfolder = "experiments/results/b"\n'
        'command = "python -c \\"raise SystemExit(3)\\" {folder}"\nsplit = "none"\nsupports = "a test"\n')
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "-c", "user.email=t@t", "-c", "user.name=t", "add", "-A")
    _git(tmp_path, "-c", "user.email=t@t", "-c", "user.name=t", "commit", "-qm", "m")
    return tmp_path


def test_results_make_records_the_clean_commit_and_refuses_a_dirty_tree(repo):
    (repo / "experiments/results/a").mkdir()
    (repo / "experiments/results/a/stale.txt").write_text("old")  # a manifest folder is made again from nothing
    [made] = manifest.make(["a"], root=repo)
    folder = repo / "experiments/results/a"
    _git(repo, "-c", "user.email=t@t", "-c", "user.name=t", "add", "-A")
    _git(repo, "-c", "user.email=t@t", "-c", "user.name=t", "commit", "-qm", "results")
    [made] = manifest.make(["a"], root=repo)  # made again over its committed self: the results' changes are not code
    assert (folder / "x.txt").read_text() == "1" and not (folder / "stale.txt").exists()
    record = manifest.read_made(folder)
    assert record == made and record["moved"] is False and record["clean_start"] and record["returncode"] == 0
    head = subprocess.run(["git", "rev-parse", "HEAD"], check=True, cwd=repo, capture_output=True, text=True).stdout.strip()
    assert record["commit_start"] == record["commit_end"] == head
    (repo / "code.py").write_text("x = 1\n")  # uncommitted code outside experiments/results
    with pytest.raises(StateError, match="uncommitted changes.*code.py"):
        manifest.make(["a"], root=repo)
    (repo / "code.py").unlink()
    with pytest.raises(StateError, match="status 3"):
        manifest.make(["fails"], root=repo)
    assert manifest.read_made(repo / "experiments/results/b")["returncode"] == 3
    with pytest.raises(ConfigError, match="not in experiments/results/MANIFEST.toml: nope"):
        manifest.make(["nope"], root=repo)


def test_manifest_entries_are_checked(tmp_path):
    (tmp_path / "experiments/results").mkdir(parents=True)
    path = tmp_path / "experiments/results/MANIFEST.toml"
    for body, msg in (('name = "a"\nfolder = "out/a"\ncommand = "hvs-sim x {folder}"\nsplit = "test"\nsupports = ""',
                       "not under experiments/results"),
                      (('name = "a"\nfolder = "experiments/results/a"\ncommand = "rm -rf {folder}"\nsplit = "test"\n'
                       'supports = ""'), "starts with hvs-sim or python"),
                      (('name = "a"\nfolder = "experiments/results/a"\ncommand = "hvs-sim x"\nsplit = "test"\n'
                       'supports = ""'), "does not write to {folder}"),
                      (('name = "a"\nfolder = "experiments/results/a"\ncommand = "hvs-sim x {folder}"\nsplit = "tuned"\n'
                       'supports = ""'), "split 'tuned'"),
                      ('name = "a"\n', "lacks command")):
        path.write_text("[[result]]\n" + body + "\n")
        with pytest.raises(ConfigError, match=msg):
            manifest.load_manifest(tmp_path)


@pytest.fixture
def published(tmp_path):
    """A copy of the repository's published tables and the folders they cite."""
    for rel in ("README.md", "docs/results.md", "experiments/results/MANIFEST.toml"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / rel, tmp_path / rel)
    for e in manifest.load_manifest(ROOT).values():
        shutil.copytree(ROOT / e.folder, tmp_path / e.folder)
    return tmp_path


def test_the_published_tables_agree_with_their_records(published):
    report = headlines.check(published)
    assert report.ok, report.text()
    assert report.figures >= 40 and report.folders >= 9  # every figure of both tables, from their folders
    assert f"{report.figures} figures" in report.text()


def test_check_fails_on_an_edited_figure_a_moved_folder_and_an_unnamed_rule(published):
    readme = published / "README.md"
    text = readme.read_text()
    i = text.index("hybrid **", text.index("results:readme begin"))
    readme.write_text(text[:i] + "hybrid **99.9 %**" + text[text.index("%**", i) + 3:])
    report = headlines.check(published)
    assert not report.ok and "README.md: table 'readme' differs from its data" in report.text()
    readme.write_text(text)
    entry = manifest.load_manifest(published)["servo_robot_cell_test"]
    made = published / entry.folder / manifest.MADE
    record = json.loads(made.read_text())
    made.write_text(json.dumps({**record, "moved": True}))
    assert "made from a dirty or moved tree" in headlines.check(published).text()
    made.write_text(json.dumps(record))
    summary = published / entry.folder / "summary.json"
    data = json.loads(summary.read_text())
    summary.write_text(json.dumps({**data, "provenance": {**data["provenance"], "commit": "0" * 40}}))
    assert "is not the clean commit MADE.json names" in headlines.check(published).text()
    summary.write_text(json.dumps(data))
    assert headlines.check(published).ok
    rows = headlines.ROWS
    try:  # a servo row that does not say which success rule its percentages are
        headlines.ROWS = [("6-DOF servo through robot_cell", lambda root, fig: f"**{fig(100.0, '.0f')} %**")]
        report = headlines.check(published)
    finally:
        headlines.ROWS = rows
    assert "does not name its success rule" in report.text()


def test_a_moved_summary_may_not_be_cited(published):
    folder = published / "experiments/results/old_run"
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps({"commit": "a" * 40, "provenance": {"commit": "b" * 40}}))
    assert headlines.check(published).ok  # not cited: allowed to exist (INDEX says what it is)
    readme = published / "README.md"
    readme.write_text(readme.read_text() + "\nSee `experiments/results/old_run/`.\n")
    assert "old_run is cited but its provenance moved" in headlines.check(published).text()


def test_no_committed_summary_names_two_commits_unmarked():
    """A summary's top-level commit (read at its start) and its provenance agree; one that does not ran while the code
    moved (before provenance recorded both ends) and INDEX.md says so, so that nobody cites it as one commit's."""
    index = (ROOT / "experiments/results/INDEX.md").read_text()
    checked = 0
    for path in sorted((ROOT / "experiments/results").rglob("summary.json")):
        data = json.loads(path.read_text())
        prov = data.get("provenance") if isinstance(data, dict) else None
        if not isinstance(prov, dict) or "commit" not in data or "commit" not in prov:
            continue
        checked += 1
        folder = str(path.parent.relative_to(ROOT / "experiments/results"))
        if "commit_end" in prov:  # written by the current code: one read at the start, one at the end
            assert data["commit"] == prov["commit"], folder
            continue
        if data["commit"] != prov["commit"]:
            rows = [line for line in index.split("\n") if line.startswith(f"| `{folder}/`")]
            assert rows and "**moved**" in rows[0], f"{folder} names two commits and INDEX.md does not mark it moved"
    assert checked >= 20
