"""``hoibench leaderboard add|build|ls``: the command's work, over
:mod:`hoibench.publish.leaderboard` (entries) and :mod:`hoibench.publish.pages` (tables).

Without ``--root`` the leaderboards folder is found by walking up from the current folder
(:func:`~hoibench.publish.leaderboard.find_root`), and the command says which one it used.
"""
from __future__ import annotations

from pathlib import Path

from . import leaderboard as lb


def resolve_root(root: str | Path | None) -> Path:
    """``root`` when given; else the nearest ``leaderboards/`` with track folders at or above
    the current folder, announced on one line."""
    if root is not None:
        root = Path(root)
        if root.exists() and not root.is_dir():
            raise NotADirectoryError(f"--root {root}: is a file, not a leaderboards folder")
        return root
    found = lb.find_root()
    if found is None:
        raise FileNotFoundError(f"no leaderboards/ folder with track folders in {Path.cwd()} or above: pass --root "
                                f"DIR (with --new-track to start a track in a new folder)")
    print(f"leaderboard root: {found} (found from {Path.cwd()}; --root chooses another)")
    return found


def main_leaderboard(action: str, root: str | Path | None = None, track: str | None = None, *,
                     result: str | Path | None = None, method: str = "", role: str = "method", notes: str = "",
                     allow_incomplete: bool = False, replace: bool = False, new_track: bool = False) -> int:
    """``hoibench leaderboard ACTION``: add a result to a track, build tracks' pages, or list
    the tracks. Returns the exit status."""
    folder = resolve_root(root)
    if not folder.exists() and not (action == "add" and new_track):
        hint = f", so it has no track {track!r} (pass --new-track to start it there)" if action == "add" else ""
        raise FileNotFoundError(f"--root {folder}: does not exist{hint}")
    if action == "add":
        path = lb.add_result(result, lb.track_folder(folder, track, new_track), method=method, role=role,
                             allow_incomplete=allow_incomplete, replace=replace, notes=notes)
        print(f"added {path}")
        return 0
    tracks = [lb.track_folder(folder, track)] if track else lb.track_dirs(folder)
    if action == "ls":
        if not folder.is_dir():
            raise FileNotFoundError(f"{folder}: no leaderboards folder")
        for t in tracks:
            entries = lb.load_track(t)
            names = ", ".join(e["method"] for e in lb.order(entries)[:4])
            print(f"{t.name:12s} {len(entries):3d} entries  ({names}{', ...' if len(entries) > 4 else ''})")
        return 0
    from .pages import build
    if not tracks:
        raise FileNotFoundError(f"{folder}: no track folders with entries/")
    for t in tracks:
        paths = build(t)
        print(f"[{t.name}] wrote " + ", ".join(str(p) for p in paths.values()))
    return 0


__all__ = ["resolve_root", "main_leaderboard"]
