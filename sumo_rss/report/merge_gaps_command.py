"""``sumo-rss merge-gaps``: its sub-command (registered by ``sumo_rss.cli``) and what it runs
(:mod:`.merge_gaps_run`)."""
from __future__ import annotations

import argparse
from pathlib import Path

EXAMPLES = """examples:
  sumo-rss run scenarios/merge_onramp.toml --controller epsilon --seed 16 --duration 160 --fcd --out results/
  sumo-rss merge-gaps results/merge_onramp__controller=epsilon/16
  sumo-rss merge-gaps results/merge_onramp__controller=epsilon/*  --change-time 3   # SUMO's lanechange.duration
"""

DESCRIPTION = ("For runs of 'sumo-rss run --fcd' whose ego merges from an acceleration lane: the earliest time a "
               "merge into the lane to its left was RSS-legal (the auditor's safe distances to every car of that "
               "lane, for the whole change, before the lane's end) and reachable from the ego's state on entering "
               "the lane within the planner's acceleration, braking and the lane's speed limit, against the merge "
               "the ego made (docs/planner.md, 'The earliest legal merge'). The other cars move as recorded; "
               "'reacting' counts those that braked for the ego or left the lane with it ahead.")


def add_merge_gaps_command(sub: argparse._SubParsersAction, common: argparse.ArgumentParser) -> None:
    cmd = sub.add_parser("merge-gaps", parents=[common], help="the earliest RSS-legal merge of a run's ego",
                         description=DESCRIPTION, epilog=EXAMPLES,
                         formatter_class=argparse.RawDescriptionHelpFormatter)
    cmd.add_argument("run_dirs", nargs="+", type=Path, metavar="RUN_DIR", help="run folder(s) with fcd.xml")
    cmd.add_argument("--change-time", type=float, metavar="S",
                     help="how long the gap must stay legal (default: the planner's barrier commit time, "
                          "SimSettings.commit_time, 1 s)")
    cmd.add_argument("--speed-step", type=float, metavar="V", help="the grid of the ego's speeds [m/s] (default 0.1)")


def run_merge_gaps(args: argparse.Namespace) -> int:
    from ..errors import SumoRssError
    from .merge_gaps import GapSearch
    from .merge_gaps_run import merge_gap_report

    given = {k: v for k, v in (("change_s", args.change_time), ("speed_step", args.speed_step)) if v is not None}
    try:
        search = GapSearch(**given)
    except ValueError as exc:
        raise SumoRssError(str(exc)) from None
    print("run | entered [s] | earliest legal start [s] (speed m/s) | its completion [s] | completed [s] | "
          "completed - earliest start [s] | within slack | reacting cars (hardest m/s²) | gap cars had reacted | "
          "same gap as taken")
    for run_dir in args.run_dirs:
        r = merge_gap_report(run_dir, search)
        e = r.earliest
        start = f"{e.start_s:.1f} ({e.speed_ms:.1f})" if e.start_s is not None else "none"
        done = f"{e.completion_s:.1f}" if e.completion_s is not None else "-"
        print(f"{r.run} | {r.entered_s:.1f} | {start} | {done} | {r.completed_s:.1f} | {r.missed_s():.1f} | "
              f"{'yes' if r.explained(search.change_s) else 'NO'} | {r.reacting_cars} ({r.hardest_reaction:.1f}) | "
              f"{'yes' if r.gap_reacted else 'no'} | {'yes' if r.same_gap else 'no'}")
    return 0
