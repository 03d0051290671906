"""Screenshot a gaitcap report.html with headless Chromium (a check for humans, not a test).

    python scripts/screenshot_report.py OUT/gait/report.html -o report.png [--height 4000]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run", "--hide-scrollbars"]  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("html", type=Path)
    ap.add_argument("-o", "--out", type=Path, default=Path("report.png"))
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=3600)
    ap.add_argument("--chromium", default=CHROMIUM)
    args = ap.parse_args(argv)
    if not args.html.is_file():
        print(f"{args.html}: not found", file=sys.stderr)
        return 1
    if shutil.which(args.chromium) is None:
        print(f"{args.chromium}: Chromium not found (apt-get install chromium, or give its path with --chromium)",
              file=sys.stderr)
        return 1
    cmd = [args.chromium, *FLAGS, f"--window-size={args.width},{args.height}",
           f"--screenshot={args.out.resolve()}", args.html.resolve().as_uri()]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    if proc.returncode != 0 or not args.out.is_file():
        print(proc.stderr[-2000:], file=sys.stderr)
        return 1
    print(f"screenshot: {args.out} ({args.out.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
