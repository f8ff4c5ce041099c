"""`make bench`: run every bench/*.py (each records into bench/results.json) and stop on the first failure. Not run:
bench/_*.py (shared code) and bench/build_*.py (they build a benchmark's input from fetched data, e.g. MoST)."""
from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    parser = argparse.ArgumentParser(
        prog="python bench/run_all.py", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  make bench\n  PYTHONPATH=. python bench/run_all.py --no-record")
    parser.add_argument("--no-record", action="store_true", help="print the figures, leave bench/results.json alone")
    passed = ["--no-record"] if parser.parse_args().no_record else []
    scripts = sorted(p for p in HERE.glob("*.py") if p.name != "run_all.py" and not p.name.startswith(("_", "build_")))
    for script in scripts:
        print(f"== {script.name}", flush=True)
        if subprocess.run([sys.executable, str(script), *passed], check=False).returncode != 0:
            print(f"{script.name} failed", file=sys.stderr)
            return 1
    if not passed:
        print(f"results: {HERE / 'results.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
