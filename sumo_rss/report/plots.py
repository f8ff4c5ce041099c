"""Report plots (matplotlib, PNG). Each function returns the figure and the data it drew."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from ..sim.snapshot import EGO_CLASS  # noqa: E402
from .summary import EGO_CATEGORIES, RESPONSIBILITY_CATEGORIES  # noqa: E402

COLOURS = {"ego": "#d62728", "ego & background": "#9467bd", "background": "#1f77b4", "none": "#bbbbbb"}


def responsibility_bars(table: pd.DataFrame) -> tuple[Figure, pd.DataFrame]:
    """Stacked bars: every pair's episodes per run label (seeds pooled) by whose violation made it someone's
    responsibility."""
    return _stacked(table, {c: c for c in RESPONSIBILITY_CATEGORIES}, "danger episodes of every vehicle pair",
                    "Who was responsible (RSS): every pair, seeds pooled"), table


def ego_responsibility_bars(table: pd.DataFrame) -> tuple[Figure, pd.DataFrame]:
    """Stacked bars: the ego's episodes per run label (seeds pooled) by who was responsible (``table``:
    summary.ego_table)."""
    columns = {category: f"responsible: {name}" for category, name in EGO_CATEGORIES.items()}
    return _stacked(table, columns, "danger episodes of the ego",
                    "Who was responsible in the ego's episodes (RSS), seeds pooled"), table


def _stacked(table: pd.DataFrame, columns: dict[str, str], xlabel: str, title: str) -> Figure:
    """Horizontal stacked bars of ``table``'s ``columns`` (colour key → column), one bar per row."""
    fig, ax = plt.subplots(figsize=(8, 0.6 * max(len(table), 2) + 1.5))
    left = pd.Series(0, index=table.index, dtype=float)
    for key, column in columns.items():
        values = table[column] if column in table else pd.Series(0, index=table.index)
        ax.barh(table.index, values, left=left, color=COLOURS[key], label=column)
        left += values
    ax.set_xlabel(xlabel)
    ax.set_title(title)
    ax.invert_yaxis()
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    fig.tight_layout()
    return fig


def violation_histogram(table: pd.DataFrame) -> tuple[Figure, pd.DataFrame]:
    """Grouped bars: violation intervals per rule (every vehicle, seeds pooled), one colour per run label."""
    fig, ax = plt.subplots(figsize=(10, 4.5))
    if not table.empty and len(table.columns):
        table.plot.bar(ax=ax, rot=15)
        ax.legend(title="run", loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    ax.set_ylabel("violation intervals")
    ax.set_title("Violations of the proper response, by rule: every vehicle, seeds pooled")
    fig.tight_layout()
    return fig, table


def pair_timeline(states: pd.DataFrame, episode: pd.Series) -> tuple[Figure, pd.DataFrame]:
    """Gap and safe distance over time for one episode (longitudinal and lateral), the danger shaded."""
    data = states[(states.run_id == episode.run_id) & (states.episode_key == episode.episode_key)]
    data = data.sort_values("time_s")
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for ax, kind in zip(axes, ("lon", "lat")):
        # Numbers, also where a batch CSV holds empty cells (junction pairs have no lateral gap) and reads as text.
        gap, d_min = (pd.to_numeric(data[f"{kind}_{name}_m"], errors="coerce") for name in ("gap", "d_min"))
        ax.plot(data.time_s, gap, label=f"{kind} gap")
        ax.plot(data.time_s, d_min, "--", label=f"{kind} d_min")
        ax.axvspan(episode.t_b_s, episode.t_end_s, color="#d62728", alpha=0.12, label="danger")
        ax.set_ylabel("m")
        ax.legend(loc="best", fontsize="small")
    names = [f"{side} = {episode.get(f'vehicle_{side}', side)}"
             f"{' (ego)' if episode.get(f'class_{side}') == EGO_CLASS else ''}" for side in ("a", "b")]
    axes[0].set_title(f"{episode.episode_key} ({episode.run_id}), {', '.join(names)}:\n"
                      f"a owes {episode.owed_a or '-'}, b owes {episode.owed_b or '-'}; "
                      f"responsible: {episode.responsible}", fontsize="small")  # two lines: the run ids are long
    axes[1].set_xlabel("time [s]")
    fig.tight_layout()
    return fig, data


def ego_speed(traces: dict[str, pd.DataFrame]) -> tuple[Figure, dict[str, pd.DataFrame]]:
    """The ego's speed over time, one line per run."""
    fig, ax = plt.subplots(figsize=(8, 4))
    for label, trace in traces.items():
        ax.plot(trace.time_s, trace.speed_ms, label=label)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("ego speed [m/s]")
    ax.set_title("Ego speed")
    if traces:
        ax.legend(fontsize="small")
    fig.tight_layout()
    return fig, traces
