"""Regenerate docs/img/viewer_cut_in.png and docs/img/viewer_junction.png: the replay viewer at a dangerous cut-in
(highway_dense) and at a junction conflict (intersection_tls), each 120 s, seed 0, every vehicle recorded.

The episodes are chosen by rule, not by hand: the cut-in is the same-direction episode that began when lateral
safety was lost (trigger 'lat') with a responsible car, lasting at least 1 s, whose cars were closest along the lane
at t_b; the junction conflict is the intersection episode with a responsible car (else any) that went deepest into
danger (smallest longitudinal margin). Each is shown 1 s after its t_b (half-way through a shorter one), centred on
the pair.

    PYTHONPATH=. .venv/bin/python docs/make_screenshots.py     # needs chromium (Debian: apt-get install chromium)
"""
from __future__ import annotations

import argparse
import io
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from PIL import Image

from sumo_rss.rss.episode_states import EpisodeStates
from sumo_rss.view import Trajectories
from sumo_rss.view.browser import headless_chromium, open_view

REPO = Path(__file__).resolve().parent.parent
IMAGES = REPO / "docs" / "img"
SECONDS = "120"
COLOURS = 256  # palette size of the PNGs (small files; the viewer's flat colours survive)


def cut_in(episodes: pd.DataFrame, run: Path) -> pd.Series:
    chosen = episodes[(episodes.trigger == "lat") & (episodes.situation == "same-direction") &
                      (episodes.responsible != "none") & (episodes.duration_s >= 1.0)]
    states = EpisodeStates.read(run / "episode_states.npz")
    rows = states.rows()
    gap_at_t_b = chosen.episode_key.map(lambda key: states.lon_gap[rows[key][0]])
    return chosen.assign(gap=gap_at_t_b).sort_values(["gap", "t_b_s"], kind="stable").iloc[0]


def junction_conflict(episodes: pd.DataFrame, run: Path) -> pd.Series:
    crossing = episodes[episodes.situation.str.startswith("intersection")]
    blamed = crossing[crossing.responsible != "none"]
    return (blamed if len(blamed) else crossing).sort_values(["min_lon_margin_m", "t_b_s"], kind="stable").iloc[0]


def run_and_view(scenario: str, out: Path) -> Path:
    subprocess.run([sys.executable, "-m", "sumo_rss", "run", str(REPO / "scenarios" / f"{scenario}.toml"),
                    "--duration", SECONDS, "--fcd", "--quiet", "--out", str(out)], check=True, cwd=REPO)
    run = out / scenario / "0"
    subprocess.run([sys.executable, "-m", "sumo_rss", "view", str(run)], check=True, cwd=REPO)
    return run


def screenshot(browser, run: Path, episode: pd.Series, target: Path) -> None:
    page = open_view(browser, run / "view.html", width=1280, height=760)
    keys = page.evaluate("sumoRssViewer.header.episodes.episode_key")
    page.evaluate(f"sumoRssViewer.selectEpisode({keys.index(episode.episode_key)})")
    t = Trajectories.read(run / "trajectories.npz")
    shown = episode.t_b_s + min(1.0, episode.duration_s / 2)
    step = int(np.searchsorted(t.time, shown - 1e-6))
    rows = np.arange(t.step_start[step], t.step_start[step + 1])
    pair = rows[np.isin(t.ids[t.vehicle[rows]], [episode.vehicle_a, episode.vehicle_b])]
    page.evaluate(f"sumoRssViewer.seek({step})")
    page.evaluate(f"sumoRssViewer.setView({t.x[pair].mean()}, {t.y[pair].mean()}, 7)")
    if page.errors:
        raise RuntimeError(f"{run / 'view.html'}: {page.errors}")
    image = Image.open(io.BytesIO(page.screenshot()))
    image.convert("RGB").quantize(COLOURS, method=Image.Quantize.FASTOCTREE).save(target, optimize=True)
    page.close()
    print(f"{target} ({target.stat().st_size // 1024} KB): {episode.episode_key} at {shown:.1f} s")


def main() -> None:
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    IMAGES.mkdir(exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="viewer-shots-") as tmp, headless_chromium() as browser:
        for scenario, choose, name in (("highway_dense", cut_in, "viewer_cut_in.png"),
                                       ("intersection_tls", junction_conflict, "viewer_junction.png")):
            run = run_and_view(scenario, Path(tmp))
            episodes = pd.read_csv(run / "episodes.csv", keep_default_na=False)
            screenshot(browser, run, choose(episodes, run), IMAGES / name)


if __name__ == "__main__":
    main()
