"""``sumo-rss view``: its sub-command (registered by ``sumo_rss.cli``) and what it runs."""
from __future__ import annotations

import argparse
from pathlib import Path

EXAMPLES = """examples:
  sumo-rss view results/merge_onramp/3          # -> results/merge_onramp/3/view.html (open it in a browser)
  sumo-rss view results/default/highway_dense/0 --out dense.html
  sumo-rss audit my.fcd.xml --net my.net.xml --out audit/ && sumo-rss view audit/
  sumo-rss view audit/ --net elsewhere/my.net.xml --every 10   # the net moved; a long audit: every 10th step
"""


def add_view_command(sub: argparse._SubParsersAction, common: argparse.ArgumentParser) -> None:
    view = sub.add_parser("view", parents=[common], help="an interactive replay of a run or audit (view.html)",
                          description="Write one self-contained HTML page (no server, no network needed) that "
                                      "replays a run or an offline audit top-down: the network's lanes and "
                                      "junctions, every recorded vehicle, the danger episodes' pairs joined by a "
                                      "line coloured by who is responsible, the selected pair's gaps against "
                                      "d_min and its owed responses with their bounds, violations and "
                                      "collisions on the timeline, and a sortable list of episodes. A run "
                                      "records the vehicles within 150 m of its ego (all with --fcd or without "
                                      "an ego); an audit records every vehicle of its FCD.",
                          epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    view.add_argument("run_dir", type=Path, metavar="RUN_DIR",
                      help="a run folder of 'sumo-rss run' or 'batch', or the --out folder of 'sumo-rss audit'")
    view.add_argument("--out", type=Path, help="the page to write (default: RUN_DIR/view.html)")
    view.add_argument("--net", type=Path,
                      help="the network (.net.xml), where it is no longer where the run or audit read it")
    view.add_argument("--every", type=int, default=1, metavar="N",
                      help="keep every N-th recorded step (default 1: all; for long runs, a smaller page)")


def run_view(args: argparse.Namespace) -> int:
    from .page import write_view

    print(f"view: {write_view(args.run_dir, args.out, args.net, args.every)}")
    return 0
