"""Screenshot a built leaderboard page with headless Chromium (Debian package ``chromium``),
to check that the static HTML renders in a real browser.

    hoibench leaderboard build
    python benchmarks/leaderboard_screenshot.py leaderboards/synthetic/index.html --size 1400,2000 \
        --out docs/img/leaderboard_synthetic_1400.png
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("page", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--size", default="1500,1400", help="window WIDTH,HEIGHT in pixels")
    args = ap.parse_args()
    exe = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if exe is None:
        raise SystemExit("no chromium on PATH: sudo apt-get install chromium (Debian/Ubuntu)")
    if not args.page.is_file():
        raise SystemExit(f"{args.page}: no such page (run `hoibench leaderboard build` first)")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    r = subprocess.run([exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                        f"--window-size={args.size}", f"--screenshot={args.out.resolve()}",
                        args.page.resolve().as_uri()], capture_output=True, text=True, timeout=180)
    if r.returncode != 0 or not args.out.exists():
        raise SystemExit(f"chromium failed ({r.returncode}): {r.stderr.strip()[-500:]}")
    print(f"wrote {args.out} ({args.out.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
