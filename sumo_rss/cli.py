"""The ``sumo-rss`` command line: run, batch, audit, report, merge-gaps, view, nets, train-intent.

Bad input (scenario files, options, input files, output folders) prints one line ``sumo-rss: error: ...`` and
exits with code 2; Ctrl-C exits with code 130; a bug prints one line ``sumo-rss: internal error: ...`` and exits with
code 70. ``--debug`` shows the traceback instead (docs/outputs.md, "Bad input, full disks and interruptions").
"""
from __future__ import annotations

import argparse
import math
import re
import signal
import sys
import time
import warnings
from pathlib import Path

from . import __version__
from .errors import ScenarioError, SumoRssError, shown
from .rss.params import PRESETS, EvasiveParams
from .scenario import CONTROLLERS, MAX_SEED
from .report.merge_gaps_command import add_merge_gaps_command, run_merge_gaps
from .view.command import add_view_command, run_view

EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130
EXIT_BUG = 70  # EX_SOFTWARE: not the input's fault
# Options whose value may start with '-' ('--seeds -1,2'): argparse would take it for an option and report a missing
# value instead of what is wrong with the value.
_VALUE_OPTIONS = frozenset({"--seeds", "--seed", "--duration", "--workers", "--epochs", "--train-seeds",
                            "--test-seeds"})

_RUN_EXAMPLES = """examples:
  sumo-rss run scenarios/highway_dense.toml
  sumo-rss run scenarios/highway_dense.toml --controller epsilon  # -> results/highway_dense__controller=epsilon/0/
  sumo-rss run scenarios/merge_onramp.toml --seed 3 --duration 60 --out results/ --fcd
"""
_BATCH_EXAMPLES = """examples:
  sumo-rss batch scenarios/default.toml                      # -> results/default/
  sumo-rss batch scenarios/default.toml --seeds 0:20 --workers 2
  sumo-rss batch scenarios/default.toml --duration 120 --out results/short   # every run 120 simulated s
  sumo-rss batch scenarios/highway_dense.toml scenarios/merge_onramp.toml --seeds 1,7,42 --out results/two
  sumo-rss batch scenarios/default.toml --rss-preset ad_rss krauss --out results/presets
  sumo-rss batch scenarios/highway_dense.toml --seeds 0:5 --controller epsilon sumo mpdm --workers 2
  sumo-rss batch scenarios/default.toml --ray-address auto    # on a Ray cluster (shared results folder)
"""
_REPORT_EXAMPLES = """examples:
  sumo-rss report results/default          # -> results/default/report.html and results/default/report/*.png
  sumo-rss report results/default --no-views   # without each run's view.html (and the links to them)
"""
_AUDIT_EXAMPLES = """examples:
  sumo-rss audit results/merge_onramp/3/fcd.xml --net networks/merge/merge.net.xml \\
      --vtypes results/merge_onramp/3/routes.rou.xml --collisions results/merge_onramp/3/collisions.xml \\
      --scenario results/merge_onramp/3/scenario.toml        # the run of 'sumo-rss run --help': its online audit
  sumo-rss audit my.fcd.xml --net my.net.xml --rss-preset mobileye_human --out audit/
  sumo-rss audit fcd.xml --net my.net.xml --vtypes types.add.xml,my.rou.xml --tls-states tls.xml --hold-standing
  sumo-rss audit fcd.xml --net my.net.xml --vtypes my.rou.xml --occluders buildings.poly.xml   # RSS rule 4
  (a run of your own: docs/rss.md shows the sumo command that writes fcd.xml and tls.xml)
"""
_NETS_EXAMPLES = """examples:
  sumo-rss nets build          # rebuild every networks/<name>/<name>.net.xml with netconvert
  sumo-rss nets check          # rebuild into a temporary folder and compare with the committed nets
"""
_TRAIN_INTENT_EXAMPLES = """examples:
  sumo-rss train-intent                                   # -> results/intention/intention.pt + intention.json
  sumo-rss train-intent --train-seeds 0:4 --test-seeds 100,101 --workers 2 --epochs 12
  sumo-rss train-intent --scenarios scenarios/highway_dense.toml --all-samples --duration 60 --out results/hw
  sumo-rss train-intent --scenarios scenarios/merge_onramp.toml --duration 120 --out results/merge_intent
  sumo-rss train-intent --out results/intention --reuse-data   # retrain on the data recorded before
  (to ship new weights, copy intention.pt and intention.json to sumo_rss/planner/intention/weights/)
"""


def _parse_seeds(text: str) -> list[int]:
    """``A:B`` (A included, B excluded) or a comma list ``1,4,9``."""
    from .batch.spec import parse_seeds

    try:
        return list(parse_seeds(text))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"expected a finite number of seconds > 0, got {shown(text)}")
    return value


def _positive_int(text: str) -> int:
    if not (text.isascii() and text.isdigit()) or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {shown(text)}")
    return int(text)


def _seed(text: str) -> int:
    if not (text.isascii() and text.isdigit()) or int(text) > MAX_SEED:
        raise argparse.ArgumentTypeError(f"expected an integer in [0, {MAX_SEED}], got {shown(text)}")
    return int(text)


def _file_list(text: str) -> list[Path]:
    """``a.rou.xml,b.add.xml`` → paths (SUMO's comma-separated file lists)."""
    files = [Path(part) for part in text.split(",") if part]
    if not files:
        raise argparse.ArgumentTypeError(f"expected one or more comma-separated files, got {shown(text)}")
    return files


class _Parser(argparse.ArgumentParser):
    """An option error as one line ``sumo-rss: error: ...`` (argparse prints its usage first), exit code 2."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"sumo-rss: error: {' '.join(message.split())}\n")


def build_parser() -> argparse.ArgumentParser:
    # --debug is accepted before or after the command; SUPPRESS keeps a sub-command from resetting it.
    common = _Parser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show tracebacks for errors")
    parser = _Parser(
        prog="sumo-rss",
        description="Responsibility-aware traffic simulation: SUMO co-simulation with an RSS auditor.",
        epilog="Run 'sumo-rss COMMAND --help' for the options and examples of a command.")
    parser.add_argument("--debug", action="store_true", help="show tracebacks for errors")
    parser.add_argument("--version", action="version", version=f"sumo-rss {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    run = sub.add_parser("run", parents=[common], help="co-simulate one scenario with one seed",
                         description="Co-simulate one scenario and write its run directory "
                                     "OUT/<scenario>/<seed>/ (resolved scenario.toml, summary.json, SUMO logs); "
                                     "with --controller C, OUT/<scenario>__controller=C/<seed>/, as a batch's "
                                     "controller sweep names it. Ctrl-C (or SIGTERM) ends the run after the "
                                     "current step and writes it up to there (summary status 'interrupted', exit "
                                     "code 130); a second Ctrl-C aborts without results.",
                         epilog=_RUN_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    run.add_argument("scenario", type=Path, help="scenario TOML file")
    run.add_argument("--seed", type=_seed, help="random seed (default: the scenario's)")
    run.add_argument("--duration", type=_positive_float, metavar="S",
                     help="simulated seconds (default: the scenario's)")
    run.add_argument("--controller", choices=CONTROLLERS,
                     help="who drives the ego: EPSILON, SUMO, SUMO held to RSS by the ego's guard (sumo_restricted) "
                          "or the MPDM baseline (default: the scenario's)")
    run.add_argument("--out", type=Path, default=Path("results"), help="results folder (default: results/)")
    run.add_argument("--fcd", action="store_true",
                     help="also write SUMO's FCD trace (fcd.xml) with accelerations and lateral position/speed")
    run.add_argument("--quiet", action="store_true", help="no progress bar")

    batch = sub.add_parser("batch", parents=[common], help="run scenarios x seeds x variants",
                           description="Run every scenario (batch files or single scenario files) with every seed "
                                       "and every variant of the grid, in parallel. Finished runs are skipped when "
                                       "the batch is run again; a failing run is recorded "
                                       "(<run>.failed/failed.json) and the batch goes on.",
                           epilog=_BATCH_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    batch.add_argument("specs", nargs="+", type=Path, metavar="SPEC",
                       help="batch file ([batch] table) or scenario file")
    batch.add_argument("--seeds", type=_parse_seeds, help="A:B (B excluded) or 1,2,3 (default: the file's)")
    batch.add_argument("--duration", type=_positive_float, metavar="S",
                       help="simulated seconds of every run (default: each scenario's)")
    batch.add_argument("--workers", type=_positive_int, default=1, help="parallel local processes (default 1)")
    batch.add_argument("--ray-address", metavar="ADDR",
                       help="run on Ray: 'auto', 'host:port' or 'local' (needs the 'ray' extra)")
    batch.add_argument("--rss-preset", nargs="+", choices=PRESETS, metavar="P",
                       help="sweep these RSS presets (replaces the files' rss_preset grid)")
    batch.add_argument("--controller", nargs="+", choices=CONTROLLERS, metavar="C",
                       help="sweep these ego controllers: sumo, sumo_restricted, epsilon, mpdm (replaces the files' "
                            "controller grid)")
    batch.add_argument("--out", type=Path, help="batch folder (default: results/<name of the first SPEC>)")
    batch.add_argument("--quiet", action="store_true", help="no progress bar")

    report = sub.add_parser("report", parents=[common], help="tables, PNG plots and report.html of a batch",
                            description="Summarise a batch folder: per-scenario responsibility, violation types, "
                                        "rules 5 and 4 (evasive effort, occlusion; 'off' where a scenario left "
                                        "them off), a pair timeline and the ego's speed, as PNGs and one "
                                        "self-contained HTML whose tables link each run's replay (view.html, "
                                        "written beside the run where it is missing or older than the run).",
                            epilog=_REPORT_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    report.add_argument("batch_dir", type=Path, help="a batch folder (with batch_summary.csv)")
    report.add_argument("--no-views", dest="views", action="store_false",
                        help="do not write each run's replay page (view.html, as 'sumo-rss view' writes it) nor "
                             "link the tables' rows to them")
    report.add_argument("--quiet", action="store_true", help="no progress bar")

    audit = sub.add_parser("audit", parents=[common], help="audit a SUMO FCD file offline",
                           description="Audit every vehicle pair of a SUMO FCD file for RSS responsibility and "
                                       "write episodes.csv, violations.csv, collisions.csv and rss_params.json. "
                                       "Ctrl-C (or SIGTERM) ends the audit after the current time step and "
                                       "writes it up to there (exit code 130); a second Ctrl-C aborts.",
                           epilog=_AUDIT_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    audit.add_argument("fcd", type=Path, help="SUMO FCD file (sumo --fcd-output)")
    audit.add_argument("--net", type=Path, required=True, help="the SUMO network of the run (.net.xml)")
    audit.add_argument("--vtypes", type=_file_list, metavar="FILE[,FILE...]",
                       help="route/vType file(s) of the run, comma-separated as for sumo -r: vehicle sizes and "
                            "dynamics (SUMO's vClass defaults where a vType leaves them out), routes (default: "
                            "SUMO's built-in vTypes only)")
    audit.add_argument("--collisions", type=Path,
                       help="SUMO collision-output file (default: collisions from overlapping bounding boxes, "
                            "which is not SUMO's own check: SUMO compares gaps along a lane with a share of minGap "
                            "(--collision.mingap-factor) and junctions only with --collision.check-junctions; a car "
                            "that SUMO's default --collision.action teleport moves away never overlaps. Give the file "
                            "for SUMO's collisions)")
    audit.add_argument("--tls-states", type=Path,
                       help="SUMO signal-state file, written by an additional file holding <timedEvent "
                            "type=\"SaveTLSStates\" dest=\"tls.xml\"/>; default: the net's fixed-time programs "
                            "(other programs: equal priority, with a warning)")
    audit.add_argument("--scenario", type=Path,
                       help="the run's scenario.toml: its RSS preset, [rss.*] overrides, hold_standing and signal "
                            "rule, as the online audit used them (instead of the three options below)")
    audit.add_argument("--rss-preset", choices=PRESETS,
                       help="RSS parameter preset (default: ad_rss; docs/rss.md lists them)")
    audit.add_argument("--hold-standing", action="store_true",
                       help="a car standing still does not accelerate during its response time (CARLA's RSS "
                            "sensor; [rss] hold_standing in scenarios)")
    audit.add_argument("--no-signal-rule", action="store_true",
                       help="do not report red-light / avoidable yellow-light entries as violations")
    audit.add_argument("--raw-episodes", action="store_true",
                       help="an episode that re-opens within the pair's response time of its end is a new episode "
                            "(default: it continues the previous one; docs/rss.md)")
    audit.add_argument("--junction-brake-min", action="store_true",
                       help="a car owing braking at a junction must brake at b_min until stopped even if it stops "
                            "before the conflict area (ad_rss's reading; default: a car that stays out complied)")
    audit.add_argument("--evasive-effort", action="store_true",
                       help="RSS rule 5: whether the car that complied could have evaded a collision with a legal "
                            "manoeuvre (episodes.csv evasive_*, rule5_responsible, collisions.csv could_have_avoided; "
                            "off by default: docs/rss.md 'Rule 5')")
    audit.add_argument("--occluders", type=_file_list, metavar="FILE[,FILE...]",
                       help="RSS rule 4 (occlusion): SUMO additional file(s) whose <poly> elements of a type starting "
                            "with 'building' block the line of sight; responses are owed from when the cars can "
                            "see each other (occlusion.csv; docs/rss.md 'Rule 4')")
    audit.add_argument("--occlusion", action="store_true",
                       help="RSS rule 4 with tall road users (vType height > 1.6 m) as the only occluders (implied "
                            "by --occluders)")
    audit.add_argument("--ego", action="append", default=[], metavar="ID",
                       help="vehicle id audited with the ego parameters (repeatable; vType 'ego_type' always is)")
    audit.add_argument("--run-id", help="run id in the CSVs (default: <folder of folder>/<folder> of the FCD)")
    audit.add_argument("--out", type=Path, default=Path("audit"), help="output folder (default: audit/)")
    audit.add_argument("--quiet", action="store_true", help="no progress bar")

    add_merge_gaps_command(sub, common)
    add_view_command(sub, common)

    nets = sub.add_parser("nets", parents=[common], help="build or check the SUMO networks",
                          description="Build networks/<name>/<name>.net.xml from their plain-XML sources with "
                                      "SUMO's netconvert, or check that the committed nets are up to date.",
                          epilog=_NETS_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    nets.add_argument("action", choices=("build", "check"))
    nets.add_argument("--root", type=Path, help="networks folder (default: $SUMO_RSS_NETWORKS if set, else the "
                                                "repository's networks/)")

    intent = sub.add_parser("train-intent", parents=[common], help="train the intention estimator",
                            description="Record labelled intention samples from libsumo runs of the scenarios "
                                        "(without ego), train the network on CPU, evaluate it against the rule-based "
                                        "belief on held-out seeds and write intention.pt and its card "
                                        "intention.json.",
                            epilog=_TRAIN_INTENT_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    intent.add_argument("--scenarios", nargs="+", type=Path, metavar="TOML",
                        help="scenario files (default: the shipped intersection_tls, intersection_priority and "
                             "merge_onramp)")
    intent.add_argument("--train-seeds", type=_parse_seeds, default=list(range(10)),
                        help="A:B (B excluded) or 1,2,3 (default 0:10)")
    intent.add_argument("--test-seeds", type=_parse_seeds, default=[100, 101, 102],
                        help="held-out seeds, never trained on (default 100:103)")
    intent.add_argument("--duration", type=_positive_float, metavar="S",
                        help="simulated seconds per run (default: the scenario's)")
    intent.add_argument("--epochs", type=_positive_int, default=30, help="training epochs (default 30)")
    intent.add_argument("--seed", type=_seed, default=0, help="training seed (default 0)")
    intent.add_argument("--workers", type=_positive_int, default=1,
                        help="parallel SUMO processes for recording (default 1)")
    intent.add_argument("--all-samples", action="store_true",
                        help="also record samples where lanes do not branch (CFB uses the rules there)")
    intent.add_argument("--reuse-data", action="store_true",
                        help="reuse OUT/train.npz and OUT/test.npz when they were recorded with the same settings")
    intent.add_argument("--out", type=Path, default=Path("results/intention"),
                        help="output folder (default: results/intention)")
    intent.add_argument("--quiet", action="store_true", help="no progress bars")
    return parser


def _cmd_run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from .batch.runner import run_directory, run_one
    from .batch.spec import Task, variant_name
    from .files import check_output_folder
    from .scenario import load_scenario

    check_output_folder(args.out, "--out")
    spec = load_scenario(args.scenario).with_overrides(seed=args.seed, duration_s=args.duration,
                                                       controller=args.controller)
    with tqdm(total=round(spec.duration_s, 3), unit="sim s", disable=args.quiet, file=sys.stderr,
              bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} sim s [{elapsed}<{remaining}]") as bar:
        def on_step(t: float) -> None:
            bar.n = round(t, 3)
            if round(t / spec.step_s) % 50 == 0:
                bar.refresh()

        # Runs with another controller go to their own folder, as in a batch sweep, not over the scenario's run.
        variant = variant_name({"controller": args.controller}) if args.controller else ""
        stop = _StopRequest.on_signals("the run")
        summary = run_one(spec, args.out, variant=variant, fcd=True if args.fcd else None, on_step=on_step,
                          stop=stop)
    ended = f"interrupted at {summary.sim_time_s:g} s: " if summary.status == "interrupted" else ""
    print(f"{spec.name} seed {spec.seed}: {ended}{summary.steps} steps, {summary.vehicles_inserted} vehicles "
          f"(peak {summary.peak_vehicles}), {summary.collisions} collisions, {summary.teleports} teleports, "
          f"{summary.episodes} RSS episodes, {summary.real_time_factor:.0f}x real time "
          f"-> {run_directory(args.out, Task(spec, variant))}")
    return EXIT_INTERRUPTED if ended else 0


class _StopRequest:
    """Ctrl-C (or SIGTERM) during ``run`` or ``audit``: the first ends the work after the current step, its results
    written up to there; the second aborts at once (nothing is written)."""

    def __init__(self, work: str) -> None:
        self.requested = False
        self._work = work

    @classmethod
    def on_signals(cls, work: str) -> _StopRequest:
        """A request that Ctrl-C and SIGTERM make from now on."""
        stop = cls(work)
        signal.signal(signal.SIGINT, stop.request)
        signal.signal(signal.SIGTERM, stop.request)
        return stop

    def request(self, signum: int, frame: object) -> None:
        from tqdm import tqdm

        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        tqdm.write(f"sumo-rss: stopping after this step and writing {self._work} up to it (Ctrl-C again: abort, "
                   "nothing written)", file=sys.stderr)

    def __call__(self) -> bool:
        return self.requested


def _cmd_batch(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from .batch.aggregate import BATCH_FILES
    from .batch.executors import LocalExecutor, RayExecutor
    from .batch.orchestrator import run_batch
    from .batch.spec import BatchSpec, load_batch
    from .files import check_output_folder
    from .scenario import load_scenario
    from .validation import read_toml

    out = args.out or Path("results") / args.specs[0].stem
    check_output_folder(out, "--out" if args.out else f"the batch folder (default for {args.specs[0]})", BATCH_FILES)
    tasks = []
    for path in args.specs:
        try:
            is_batch = "batch" in read_toml(path, "batch")
        except (OSError, ScenarioError):
            is_batch = False  # load_scenario reports what is wrong with it
        if is_batch:
            spec = load_batch(path)
        else:
            scenario = load_scenario(path)
            spec = BatchSpec(path, (scenario,), (scenario.seed,), {})
        if args.seeds is not None:
            spec = replace(spec, seeds=tuple(args.seeds))
        if args.duration is not None:
            spec = replace(spec, scenarios=tuple(s.with_overrides(duration_s=args.duration) for s in spec.scenarios))
        swept = {key: tuple(values) for key, values in (("rss_preset", args.rss_preset),
                                                         ("controller", args.controller)) if values}
        spec = replace(spec, grid={**spec.grid, **swept})  # the command line's sweeps replace the file's
        tasks += spec.tasks()
    executor = RayExecutor(args.ray_address) if args.ray_address else LocalExecutor(args.workers)
    # A scheduler's or timeout's stop: as Ctrl-C, finished runs are kept. Set once the executor is there: ray.init
    # installs a handler of its own (exit code 15).
    signal.signal(signal.SIGTERM, _interrupt)
    rows = run_batch(tasks, out, executor, progress=not args.quiet)
    failed = int((rows.status != "ok").sum())
    print(f"{len(rows) - failed} runs ok, {failed} failed -> {out / 'batch_summary.csv'}")
    return 1 if failed else 0


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def _cmd_report(args: argparse.Namespace) -> int:
    from .files import check_output_folder
    from .report.html import REPORT_FILES, write_report

    if args.batch_dir.is_dir():  # else write_report says what is missing
        check_output_folder(args.batch_dir, "the batch folder", REPORT_FILES)
    html = write_report(args.batch_dir, views=args.views, progress=not args.quiet)
    print(f"report: {html}")
    return 0


def _cmd_audit(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from .batch.runner import param_resolver
    from .files import check_output_folder, scratch_folder
    from .rss.auditor import AUDIT_FILES, ParamResolver
    from .rss.occlusion import OcclusionParams, read_occluders
    from .rss.fcd import AuditProgress, FcdError, audit_fcd, read_vehicle_info
    from .scenario import load_scenario
    from .view.trajectories import TRAJECTORY_FILE, TrajectoryRecorder

    check_output_folder(args.out, "--out", (*AUDIT_FILES, TRAJECTORY_FILE))  # before the work, not after a long audit
    for path, what in ((args.fcd, "FCD"), (args.net, "network"), *((p, "vType") for p in args.vtypes or ()),
                       *((p, "occluder") for p in args.occluders or ()),
                       (args.collisions, "collision"), (args.tls_states, "signal-state")):
        if path is not None and not path.is_file():
            raise FcdError(f"{path}: {what} file not found" + (" (a folder stands there; expected a file)"
                                                                  if path.is_dir() else ""))
    # Where the time goes before the first step (a city network's first load takes seconds), on a terminal only: an
    # error stays the one line on stderr that scripts read.
    shown = not args.quiet and sys.stderr.isatty()
    say = (lambda text: print(f"audit: {text}", file=sys.stderr, flush=True)) if shown else (lambda _: None)
    say(f"loading the network {args.net} ...")
    started = time.perf_counter()
    network, topology, junctions = _read_network(args.net)  # before the vTypes, which SUMO loads on this network
    say(f"network of {len(network.edge_ids)} edges, {len(junctions.links)} junction links and "
        f"{len(junctions.conflicts)} conflict areas ready in {time.perf_counter() - started:.1f} s")
    vehicles = read_vehicle_info(args.vtypes, args.net)
    if args.scenario is not None:
        if args.rss_preset or args.hold_standing or args.no_signal_rule or args.raw_episodes or \
                args.junction_brake_min or args.evasive_effort or args.occluders or args.occlusion:
            raise SumoRssError("--scenario sets the RSS parameters and rules: leave out --rss-preset, --hold-standing, "
                               "--no-signal-rule, --raw-episodes, --junction-brake-min, --evasive-effort, "
                               "--occluders and --occlusion")
        spec = load_scenario(args.scenario)
        resolver = param_resolver(spec)
        rules = dict(signal_rule=spec.rss.signal_rule, raw_episodes=spec.rss.raw_episodes,
                     junction_brake_min=spec.rss.junction_brake_min, evasive=spec.rss.evasive,
                     occlusion=spec.rss.occlusion)
    else:
        resolver = ParamResolver(args.rss_preset or "ad_rss", vtype_dynamics=vehicles.dynamics,
                                 hold_standing=args.hold_standing)
        rules = dict(signal_rule=not args.no_signal_rule, raw_episodes=args.raw_episodes,
                     junction_brake_min=args.junction_brake_min,
                     evasive=EvasiveParams(enabled=True) if args.evasive_effort else None,
                     occlusion=OcclusionParams(enabled=True, occluders=tuple(args.occluders or ()))
                     if args.occluders or args.occlusion else None)
    occluders = rules["occlusion"].occluders if rules["occlusion"] is not None else ()
    rules["occluders"] = read_occluders(occluders) if occluders else None
    fcd = args.fcd.resolve()
    run_id = args.run_id or f"{fcd.parent.parent.name}/{fcd.parent.name}"
    # What 'sumo-rss view' replays (every vehicle, every episode's steps) goes to disk as it is recorded, so that
    # memory is bounded by the traffic at one time, not by the length of the run (docs/viewer.md).
    with scratch_folder(args.out) as spool:
        # Shown from 0.5 s on: not for a short audit, nor before an error in the file's first steps.
        with tqdm(total=args.fcd.stat().st_size, unit="B", unit_scale=True, desc="audit", disable=args.quiet,
                  file=sys.stderr, delay=0.5) as bar:
            begun, done = time.perf_counter(), [AuditProgress(0, 0.0, 0, 0)]

            def on_progress(progress: AuditProgress) -> None:
                done[0] = progress
                rate = progress.pair_steps / max(time.perf_counter() - begun, 1e-9)
                bar.set_postfix_str(f"t={progress.time:.0f} s, {rate / 1e3:.0f}k pair-steps/s", refresh=False)
                bar.update(progress.bytes_read - bar.n)

            stop = _StopRequest.on_signals("the audit")
            recorder = TrajectoryRecorder(args.net, spool=spool)  # every vehicle
            result = audit_fcd(args.fcd, network, resolver, vehicles=vehicles,
                               collisions=args.collisions, tls_states=args.tls_states, ego_ids=tuple(args.ego),
                               run_id=run_id, **rules, on_progress=on_progress, stop=stop, record_states=True,
                               spool=spool, on_snapshot=recorder.add)
            if not stop.requested:
                bar.update(bar.total - bar.n)  # read to its end
        result.to_csv(args.out, also={TRAJECTORY_FILE: recorder.write})
    signals = "" if args.tls_states or not topology.signals else \
        f" (the states of the network's {len(topology.signals)} signals from its own programs: no --tls-states)"
    print(f"{'interrupted: ' if stop.requested else ''}{len(result.episodes)} episodes, {len(result.violations)} "
          f"violations, {len(result.collisions)} collisions{signals} -> {args.out} ({done[0].steps} steps, "
          f"{done[0].pair_steps} pair-steps, audited in {time.perf_counter() - begun:.1f} s)"
          + (f"; rule 4: {len(result.occlusion)} episodes hidden at some step, {result.occluded_pair_steps} "
             "hidden pair-steps" if result.occlusion is not None else ""))
    return EXIT_INTERRUPTED if stop.requested else 0


def _read_network(path: Path):
    """The road model, the topology index and the junction model of ``path`` (built once: the auditor takes it from
    the road model cache); FcdError naming the file, element and attribute where it is not a SUMO network the road
    model can use (:mod:`sumo_rss.road.net_check`)."""
    from .road.junctions import JunctionModel
    from .road.network import RoadNetwork
    from .road.topology import read_topology
    from .rss.fcd import FcdError

    try:
        topology = read_topology(path)
    except ValueError as exc:  # it names the file
        raise FcdError(str(exc)) from None
    try:
        network = RoadNetwork.from_file(path)
        return network, topology, JunctionModel.from_file(path, network)
    except (KeyError, IndexError, ValueError, TypeError, AttributeError) as exc:  # what sumolib raises on the rest
        raise FcdError(f"{path}: not a SUMO network the road model can use ({type(exc).__name__}: {exc})") from None


def _cmd_nets(args: argparse.Namespace) -> int:
    import tempfile

    from .road.build import build_network, network_dirs, without_generator_header
    from .scenario import networks_root

    root = args.root or networks_root()
    dirs = network_dirs(root)
    if not dirs:
        raise SumoRssError(f"{root}: no networks found (expected <name>/<name>.netccfg)")
    stale, broken = [], []
    for d in dirs:  # every network is tried: one that netconvert refuses does not hide the others
        try:
            if args.action == "build":
                print(f"built {build_network(d)}")
                continue
            with tempfile.TemporaryDirectory() as tmp:
                fresh = build_network(d, Path(tmp) / "check.net.xml").read_text(encoding="utf-8")
        except SumoRssError as exc:
            print(f"sumo-rss: error: {exc}", file=sys.stderr)
            broken.append(d.name)
            continue
        committed_file = d / f"{d.name}.net.xml"
        if not committed_file.is_file():
            print(f"{d.name}: MISSING {committed_file.name} (run: sumo-rss nets build)")
            stale.append(d.name)
            continue
        same = without_generator_header(fresh) == without_generator_header(committed_file.read_text(encoding="utf-8"))
        print(f"{d.name}: {'up to date' if same else 'STALE (run: sumo-rss nets build)'}")
        stale += [] if same else [d.name]
    return EXIT_BAD_INPUT if broken else 1 if stale else 0


def _cmd_train_intent(args: argparse.Namespace) -> int:
    from .files import check_output_folder
    from .planner.intention.pipeline import DEFAULT_SCENARIOS, DataPlan, summary_lines, train_intent
    from .planner.intention.train import TrainSettings

    check_output_folder(args.out, "--out")

    shipped = Path(__file__).resolve().parent.parent / "scenarios"
    paths = args.scenarios or [shipped / f"{name}.toml" for name in DEFAULT_SCENARIOS]
    if args.epochs < 1:
        raise SumoRssError(f"--epochs: expected an integer >= 1, got {args.epochs}")
    if set(args.train_seeds) & set(args.test_seeds):
        raise SumoRssError(f"--test-seeds must not repeat --train-seeds (both: "
                           f"{sorted(set(args.train_seeds) & set(args.test_seeds))})")
    plan = DataPlan(tuple(paths), tuple(args.train_seeds), tuple(args.test_seeds), args.duration, args.all_samples)
    card = train_intent(plan, args.out, TrainSettings(epochs=args.epochs, seed=args.seed), workers=args.workers,
                        reuse_data=args.reuse_data, show_progress=not args.quiet)
    print("\n".join(summary_lines(card)))
    print(f"weights: {args.out / 'intention.pt'} ({card['weights_bytes']} bytes), card: {args.out / 'intention.json'}")
    return 0


def _print_warning(message: Warning | str, *_: object, **__: object) -> None:
    """Warnings as one line of their own, also while a progress bar is shown (``--debug`` shows Python's form, with
    the code that warned)."""
    from tqdm import tqdm

    tqdm.write(f"sumo-rss: warning: {' '.join(str(message).split())}", file=sys.stderr)


def _join_negative_values(argv: list[str]) -> list[str]:
    """``--seeds -1,2`` as ``--seeds=-1,2``, so that the option's own check says what is wrong with the value."""
    joined: list[str] = []
    for token in argv:
        if joined and joined[-1] in _VALUE_OPTIONS and re.match(r"-[\d.,:]", token):
            joined[-1] = f"{joined[-1]}={token}"
        else:
            joined.append(token)
    return joined


def _one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line; an OSError with the file it is about (``[Errno 2] No such file or
    directory: 'x'`` as ``x: No such file or directory``)."""
    if isinstance(exc, OSError) and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
    else:
        text = str(exc)
    return " ".join(text.split())


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(_join_negative_values(sys.argv[1:] if argv is None else list(argv)))
    except SystemExit as exc:  # --help, --version, or an option error (printed)
        return int(exc.code or 0)
    handler = {"run": _cmd_run, "batch": _cmd_batch, "audit": _cmd_audit, "report": _cmd_report,
               "merge-gaps": run_merge_gaps, "view": run_view, "nets": _cmd_nets,
               "train-intent": _cmd_train_intent}[args.command]
    try:
        with warnings.catch_warnings():
            if not args.debug:
                warnings.showwarning = _print_warning
            return handler(args)
    except (SumoRssError, OSError) as exc:  # OSError: a path that cannot be read or written (it names the file)
        if args.debug:
            raise
        print(f"sumo-rss: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("sumo-rss: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:  # a bug, not bad input: one line, the traceback with --debug
        if args.debug:
            raise
        print(f"sumo-rss: internal error: {type(exc).__name__}: {_one_line(exc)} (a bug, not your input: please "
              "report it with the output of the same command with --debug)", file=sys.stderr)
        return EXIT_BUG


if __name__ == "__main__":  # ``python -m sumo_rss.cli``, as ``python -m sumo_rss``
    raise SystemExit(main())
