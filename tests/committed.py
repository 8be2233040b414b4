"""The checked-in leaderboards as committed, not as a user's working tree has them.

A user who follows the docs adds rows (``leaderboards/<track>/entries/*.json``) to the
working tree; tests that read the shipped tracks must not see them. In a git checkout the
files are read from ``HEAD`` (``git ls-files`` + ``git show HEAD:<path>``); outside one (an
unpacked source archive) the working tree is the release, so it is copied as it is."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _git(*args: str) -> subprocess.CompletedProcess | None:
    try:
        run = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, check=False, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return run if run.returncode == 0 else None


def committed_copy(rel: str, dest: Path) -> Path:
    """Copy the committed files under ``ROOT / rel`` (a folder) into ``dest``; returns ``dest``."""
    dest.mkdir(parents=True, exist_ok=True)
    listed = _git("ls-files", "-z", "--", rel)
    if listed is None or not listed.stdout:
        shutil.copytree(ROOT / rel, dest, dirs_exist_ok=True)
        return dest
    for name in filter(None, listed.stdout.decode().split("\0")):
        shown = _git("show", f"HEAD:{name}")
        if shown is None:                                   # staged but not yet committed: not shipped
            continue
        out = dest / Path(name).relative_to(rel)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(shown.stdout)
    return dest


def committed_track(track: str, tmp_path: Path) -> Path:
    """The committed ``leaderboards/<track>`` copied to ``tmp_path/leaderboards/<track>``."""
    return committed_copy(f"leaderboards/{track}", tmp_path / "leaderboards" / track)
