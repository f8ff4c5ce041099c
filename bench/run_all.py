"""`make bench`: run every bench/*.py (each records into bench/results.json) and stop on the first failure."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    scripts = sorted(p for p in HERE.glob("*.py") if p.name != "run_all.py" and not p.name.startswith("_"))
    for script in scripts:
        print(f"== {script.name}", flush=True)
        if subprocess.run([sys.executable, str(script)], check=False).returncode != 0:
            print(f"{script.name} failed", file=sys.stderr)
            return 1
    print(f"results: {HERE / 'results.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
