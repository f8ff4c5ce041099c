"""Report plots (matplotlib, PNG). Each function returns the figure and the data it drew."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from .summary import RESPONSIBILITY_CATEGORIES  # noqa: E402

COLOURS = {"ego": "#d62728", "ego & background": "#9467bd", "background": "#1f77b4", "none": "#bbbbbb"}


def responsibility_bars(table: pd.DataFrame) -> tuple[Figure, pd.DataFrame]:
    """Stacked bars: episodes per scenario by who was responsible."""
    fig, ax = plt.subplots(figsize=(8, 0.6 * max(len(table), 2) + 1.5))
    left = pd.Series(0, index=table.index, dtype=float)
    for category in RESPONSIBILITY_CATEGORIES:
        values = table[category] if category in table else pd.Series(0, index=table.index)
        ax.barh(table.index, values, left=left, color=COLOURS[category], label=category)
        left += values
    ax.set_xlabel("danger episodes")
    ax.set_title("Who was responsible (RSS), per scenario")
    ax.invert_yaxis()
    ax.legend(loc="lower right", fontsize="small")
    fig.tight_layout()
    return fig, table


def violation_histogram(table: pd.DataFrame) -> tuple[Figure, pd.DataFrame]:
    """Grouped bars: violations per broken rule, one colour per scenario."""
    fig, ax = plt.subplots(figsize=(8, 4))
    if not table.empty:
        table.plot.bar(ax=ax, rot=15)
    ax.set_ylabel("violations")
    ax.set_title("Violations of the proper response, by rule")
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
        ax.legend(loc="upper right", fontsize="small")
    axes[0].set_title(f"{episode.episode_key} ({episode.run_id}):\n"
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
