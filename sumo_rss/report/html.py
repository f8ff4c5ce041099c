"""``sumo-rss report``: PNG plots under ``<batch>/report/`` and one self-contained ``report.html``."""
from __future__ import annotations

import base64
import html
import io
import sys
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd

from ..errors import SumoRssError
from ..files import make_folder, read_csv_table, write_file_set
from .inputs import check_table
from .later_rules import later_rules_table, rules_on
from .plots import ego_responsibility_bars, ego_speed, pair_timeline, responsibility_bars, violation_histogram
from .summary import ego_table, read_batch_csv, responsibility_table, run_label, violation_table


FIGURES = ("ego_responsibility", "responsibility", "violations", "pair_timeline", "ego_speed")
REPORT_FILES = ("report.html",)  # written into the batch folder (and the figures into its report/ folder)


def write_report(batch_dir: Path, views: bool = True, progress: bool = False) -> Path:
    """Write the PNGs and report.html of a batch folder; returns the HTML path. ``views``: also write each run's
    replay page (``sumo-rss view``, where missing or older than the run) and link every table row to its runs'
    pages; ``progress``: a bar while they are written. Every input is read and checked first, and the report's
    outputs are written as a set (:func:`~sumo_rss.files.write_file_set`): a damaged input or a full disk leaves
    the folder as it was."""
    batch_dir = Path(batch_dir)
    path = batch_dir / "batch_summary.csv"
    if batch_dir.exists() and not batch_dir.is_dir():
        raise SumoRssError(f"{batch_dir}: is a file (expected a batch folder, as 'sumo-rss batch' writes it)")
    if not path.is_file():
        raise SumoRssError(f"{batch_dir}: no batch_summary.csv; run 'sumo-rss batch' first")
    summary = _read(batch_dir, "batch_summary")
    if summary.empty:
        raise SumoRssError(f"{path}: lists no runs")
    episodes, violations, states = (_read(batch_dir, name) for name in ("episodes", "violations", "pair_states"))
    later = later_rules_table(rules_on(batch_dir, summary), _read(batch_dir, "collisions"),
                              _read(batch_dir, "occlusion"), violations)
    traces = ego_traces(batch_dir, summary)
    labels = run_label(summary[summary.status == "ok"]).unique().tolist()  # runs with nothing to count show 0
    responsibility, broken = responsibility_table(episodes, labels), violation_table(violations, labels)
    ego = ego_table(episodes, summary)
    figures = {"ego_responsibility": ego_responsibility_bars(ego)[0],
               "responsibility": responsibility_bars(responsibility)[0], "violations": violation_histogram(broken)[0]}
    timeline = longest_traced_episode(episodes, states)
    if timeline is not None:
        figures["pair_timeline"] = pair_timeline(states, timeline)[0]
    if traces:
        figures["ego_speed"] = ego_speed(traces)[0]
    images = {}
    for name, fig in figures.items():
        png = io.BytesIO()
        fig.savefig(png, dpi=100, format="png")
        plt.close(fig)
        images[name] = png.getvalue()
    figures_dir, out = batch_dir / "report", batch_dir / "report.html"
    made = not figures_dir.exists()
    make_folder(figures_dir)  # before the runs' replay pages: a file standing there fails before anything is written
    try:
        links = _view_links(batch_dir, summary, progress) if views else {}
        page = _page(batch_dir, summary, ego, responsibility, broken, later,
                     {name: base64.b64encode(data).decode("ascii") for name, data in images.items()}, links)
        writers = {figures_dir / f"{name}.png": _bytes_writer(data) for name, data in images.items()}
        writers[out] = lambda tmp: tmp.write_text(page, encoding="utf-8")
        write_file_set(writers)
    except BaseException:
        if made:
            figures_dir.rmdir()
        raise
    for stale in set(FIGURES) - set(figures):  # a figure this batch does not have must not linger from an older one
        (figures_dir / f"{stale}.png").unlink(missing_ok=True)
    return out


def _bytes_writer(data: bytes):
    return lambda path: path.write_bytes(data)


def _view_links(batch_dir: Path, summary: pd.DataFrame, progress: bool) -> dict[str, str]:
    """run_id → the link (relative to the report) of its replay page, for the successful runs that have one."""
    from tqdm import tqdm

    from ..view.page import write_run_views

    run_ids = summary.run_id[summary.status == "ok"].astype(str).tolist()
    with tqdm(total=len(run_ids), desc="views", unit="run", disable=not progress, file=sys.stderr) as bar:
        pages = write_run_views((batch_dir / run_id for run_id in run_ids), on_done=bar.update)
    return {run_id: (batch_dir / run_id / pages[batch_dir / run_id].name).relative_to(batch_dir).as_posix()
            for run_id in run_ids if batch_dir / run_id in pages}


def _with_views(table: pd.DataFrame, labels: pd.Series, summary: pd.DataFrame, links: dict[str, str]
                ) -> pd.DataFrame:
    """``table`` (rows: run labels) with a column 'views': a link to each of the row's runs' pages, by seed."""
    runs = summary.assign(label=labels)
    runs = runs[runs.run_id.astype(str).isin(links)]
    cells = {label: " ".join(f"<a href='{html.escape(links[str(r.run_id)])}'>{html.escape(str(r.seed))}</a>"
                             for r in group.sort_values("seed").itertuples()) for label, group in runs.groupby("label")}
    return _escaped(table).assign(views=[cells.get(label, "") for label in table.index])


def _escaped(table: pd.DataFrame) -> pd.DataFrame:
    """``table`` with its text cells and index escaped for HTML (it is then written with ``escape=False``)."""
    out = table.copy()
    for column in out.columns:
        if out[column].dtype == object:
            out[column] = out[column].map(lambda v: html.escape(v) if isinstance(v, str) else v)
    out.index = pd.Index([html.escape(str(v)) for v in out.index], name=table.index.name)
    out.columns = pd.Index([html.escape(str(v)) for v in out.columns], name=table.columns.name)
    return out


def _read(batch_dir: Path, name: str) -> pd.DataFrame:
    """A batch CSV (:func:`read_batch_csv`), checked (:func:`~sumo_rss.report.inputs.check_table`; an absent one is
    an empty table); SumoRssError naming it where it is not one."""
    path = batch_dir / f"{name}.csv"
    table = read_batch_csv(batch_dir, name)
    return table if table.empty and not path.is_file() else check_table(table, path, name)


def longest_traced_episode(episodes: pd.DataFrame, states: pd.DataFrame) -> pd.Series | None:
    """The episode with the most traced steps (ego episodes are traced), preferring ones ending in a collision."""
    if episodes.empty or states.empty:
        return None
    steps = states.groupby(["run_id", "episode_key"]).size().rename("steps").reset_index()
    traced = episodes.merge(steps, on=["run_id", "episode_key"])
    if traced.empty:
        return None
    traced["collided"] = traced.collision.astype(str) == "True"
    return traced.sort_values(["collided", "steps", "run_id", "episode_key"],
                              ascending=[False, False, True, True]).iloc[0]


def ego_traces(batch_dir: Path, summary: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The ego trace of the lowest successful seed of every scenario variant whose ego was on the road."""
    traces = {}
    ok = summary[summary.status == "ok"]
    for (scenario, variant), group in ok.groupby(["scenario", "variant"], sort=True):
        for run in group.sort_values("seed").itertuples():
            path = batch_dir / run.run_id / "ego_trace.csv"
            trace = _read_trace(path) if path.is_file() else None
            if trace is not None and not trace.empty:
                traces[f"{scenario}{' [' + variant + ']' if variant else ''} seed {run.seed}"] = trace
                break
    return traces


def _read_trace(path: Path) -> pd.DataFrame:
    """A run's ego_trace.csv, checked as the batch CSVs are."""
    trace = read_csv_table(path, "'sumo-rss run'", keep_default_na=False)
    return check_table(trace, path, "ego_trace", ["time_s", "speed_ms"])


def _page(batch_dir: Path, summary: pd.DataFrame, ego: pd.DataFrame, responsibility: pd.DataFrame,
          violations: pd.DataFrame, later: pd.DataFrame, images: dict[str, str], links: dict[str, str]) -> str:
    ok = int((summary.status == "ok").sum())
    labels = run_label(summary)
    runs = _escaped(_numbers_as_numbers(summary))
    runs.insert(0, "view", [f"<a href='{html.escape(links[r])}'>view</a>" if r in links else ""
                            for r in summary.run_id.astype(str)])
    ego, responsibility, later = (_with_views(t, labels, summary, links) for t in (ego, responsibility, later))
    per_label = _with_views(pd.DataFrame(index=violations.columns), labels, summary, links)["views"]
    rules = _escaped(violations)
    violations = pd.concat([rules, pd.DataFrame([per_label.tolist()], index=["views"], columns=rules.columns)])
    violations.index.name = rules.index.name

    def image(name: str) -> list[str]:
        return [f"<img alt='{name}' src='data:image/png;base64,{images[name]}'>"] if name in images else []

    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'>",
        f"<title>sumo_rss report: {html.escape(batch_dir.name)}</title>",
        "<style>body{font-family:sans-serif;margin:2em;max-width:1100px}table{border-collapse:collapse;"
        "font-size:small}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}"
        "img{max-width:100%}</style></head><body>",
        f"<h1>sumo_rss batch report: {html.escape(batch_dir.name)}</h1>",
        f"<p>{ok} of {len(summary)} runs ok. Units: SI (s, m/s). One row per scenario and variant, its successful "
        "runs' seeds pooled; 'views' links each run's replay (by seed). Responsibility follows RSS (see "
        "docs/outputs.md): a car is responsible for an episode if it broke its proper response in it.</p>",
        "<h2>The ego's danger episodes</h2>",
        "<p>Episodes of a pair with the ego, by who was responsible; the ego's mean speed is the mean over the "
        "runs of each run's mean while the ego was on the road.</p>",
        ego.to_html(float_format=lambda v: f"{v:.3f}", escape=False),
        *image("ego_responsibility"),
        "<h2>Every vehicle pair's danger episodes</h2>",
        "<p>Episodes of every pair of vehicles (the ego's included), by whose violation made the episode someone's "
        "responsibility: the ego's, the ego's and a background car's, background cars' only, nobody's.</p>",
        responsibility.to_html(escape=False), *image("responsibility"),
        "<h2>Violations by rule</h2>",
        "<p>Intervals in which a vehicle broke a rule of its proper response (every vehicle; one episode can hold "
        "several); signal rules are judged at signalised junctions when the scenario's signal rule is on.</p>",
        *image("violations"), violations.to_html(escape=False),
        "<h2>Rule 5 / rule 4: evasive effort and occlusion</h2>",
        "<p>Both rules are opt-in (docs/rss.md): rule 5 with <code>[rss] evasive_effort</code>, rule 4 with "
        "<code>[rss] occlusion</code> or <code>occluders</code>, as each run's scenario.toml says. 'off': no run of "
        "the row had the rule on (0 means it was judged and found nothing); 'N (k of n runs)': counted over the k "
        "runs that had it on. Rule 5: collisions whose other car could have avoided them by an evasive manoeuvre "
        "(collisions.csv <code>could_have_avoided</code>). Rule 4: episodes whose cars could not see each other at "
        "some step (occlusion.csv), those hidden already at the danger threshold (<code>occluded_at_t_b</code>), "
        "and hidden cars' unreasonable speeds (violations <code>occluded-unreasonable-speed</code>).</p>",
        later.to_html(escape=False),
    ]
    for name, title in (("pair_timeline", "A danger episode of the ego, step by step"), ("ego_speed", "Ego speed")):
        if name in images:
            parts += [f"<h2>{title}</h2>", *image(name)]
    parts += ["<h2>Runs</h2>", runs.to_html(index=False, float_format=lambda v: f"{v:.3f}", na_rep="", escape=False),
              "</body></html>"]
    return "\n".join(parts)


def _numbers_as_numbers(table: pd.DataFrame) -> pd.DataFrame:
    """``table`` with every column whose non-empty cells are all numbers read as numbers: a failed run's empty
    cells made its column text, printed with all 6 decimals. Whole numbers as written (no '.', no exponent: counts)
    stay whole (a float column would print 400 as 400.000)."""
    def column(values: pd.Series) -> pd.Series:
        if pd.api.types.is_bool_dtype(values):
            return values
        if pd.api.types.is_numeric_dtype(values):
            numbers, whole = values, pd.api.types.is_integer_dtype(values)
        else:
            written = values[values != ""].astype(str)
            numbers = pd.to_numeric(values.where(values != ""), errors="coerce")
            if written.empty or numbers.notna().sum() != written.size:  # all empty (e.g. 'variant'), or text
                return values
            whole = bool(written.str.fullmatch(r"-?\d+").all())
        if not whole or numbers.notna().all():
            return numbers.astype("Int64") if whole else numbers
        # Whole numbers with empty cells: pandas prints a nullable integer's NA as '<NA>' whatever na_rep says.
        return numbers.astype("Int64").astype(object).where(numbers.notna(), "")
    return table.apply(column)
