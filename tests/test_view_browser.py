"""The view page in a real headless Chromium (Debian's chromium, driven by playwright; skipped only where none can be
had): it loads without console errors, draws the recorded vehicles where they were, jumps to an episode's t_b from
the list, and charts the pair's gaps as pair_states.csv has them. One browser for the module."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from conftest import SCENARIOS, run_cli
from sumo_rss.view import Trajectories
from sumo_rss.view.browser import headless_chromium, missing_browser, open_view

CAR, EGO, GROUND = (0x9D, 0xB8, 0xD9), (0x1A, 0x98, 0x50), (0xEE, 0xEE, 0xEA)  # viewer.js's COLOUR


@pytest.fixture(scope="module")
def browser():
    reason = missing_browser()
    if reason is not None:
        pytest.skip(reason)
    with headless_chromium() as chromium:
        yield chromium


@pytest.fixture(scope="module")
def merge_view(tmp_path_factory):
    """60 s of merge_onramp (seed 0; the ego merges from the ramp at 30 s) and its view.html."""
    out = tmp_path_factory.mktemp("merge")
    proc = run_cli("run", str(SCENARIOS / "merge_onramp.toml"), "--duration", "60", "--out", str(out), "--quiet")
    assert proc.returncode == 0, proc.stderr
    run = out / "merge_onramp" / "0"
    assert run_cli("view", str(run)).returncode == 0
    return run


@pytest.fixture(scope="module")
def page(browser, merge_view):
    page = open_view(browser, merge_view / "view.html")
    yield page
    page.close()


def scene_pixel(page, x: float, y: float) -> tuple[int, ...]:
    """The scene canvas's colour at world point (x, y) [m], placed on screen from the view's centre and scale alone
    (empty outside the canvas)."""
    view = page.evaluate("sumoRssViewer.state()")["view"]
    width, height, ratio = page.evaluate("(() => { const c = document.getElementById('scene'); "
                                         "return [c.clientWidth, c.clientHeight, devicePixelRatio]; })()")
    origin = page.evaluate("sumoRssViewer.header.origin")
    sx = (x - origin[0] - view["cx"]) * view["scale"] + width / 2
    sy = height / 2 - (y - origin[1] - view["cy"]) * view["scale"]
    if not (0 <= sx < width and 0 <= sy < height):
        return ()
    return tuple(page.evaluate("([x, y]) => Array.from(document.getElementById('scene').getContext('2d')"
                               ".getImageData(x, y, 1, 1).data.slice(0, 3))", [int(sx * ratio), int(sy * ratio)]))


def busiest_step(run):
    """The trajectories, the step with the most vehicles recorded near the ego, its rows and the ego's row."""
    t = Trajectories.read(run / "trajectories.npz")
    step = int(np.argmax(np.diff(t.step_start)))
    rows = np.arange(t.step_start[step], t.step_start[step + 1])
    egos = rows[t.vclass[t.vehicle[rows]] == "ego"]
    assert len(rows) >= 8 and len(egos) == 1
    return t, step, rows, int(egos[0])


def test_the_page_loads_without_errors_and_draws_every_vehicle_where_it_was(page, merge_view):
    assert page.errors == []
    t, step, rows, ego = busiest_step(merge_view)
    page.evaluate("([x, y, k]) => { sumoRssViewer.setView(x, y, 3); sumoRssViewer.seek(k); }",
                  [float(t.x[ego]), float(t.y[ego]), step])
    view = page.evaluate("sumoRssViewer.state()")
    assert view["step"] == step and view["time"] == pytest.approx(t.time[step])
    seen = []
    for r in rows:  # each vehicle's centre: half its length behind its front bumper
        length = t.length[t.vehicle[r]]
        colour = scene_pixel(page, t.x[r] - length / 2 * np.cos(t.heading[r]),
                             t.y[r] - length / 2 * np.sin(t.heading[r]))
        if colour:
            seen.append((colour, EGO if r == ego else CAR))
    assert len(seen) >= 5
    assert seen[[expected for _, expected in seen].index(EGO)][0] == EGO
    assert sum(colour == expected for colour, expected in seen) >= 0.9 * len(seen)
    # 40 m beside the ego, off the road: the ground.
    heading = t.heading[ego]
    assert scene_pixel(page, t.x[ego] - 40 * np.sin(heading) - 2, t.y[ego] + 40 * np.cos(heading)) in (GROUND, ())


def test_a_vehicle_whose_front_bumper_is_out_of_view_is_still_drawn(page, merge_view):
    """The frame leaves out what is outside the view: not a car whose front is 2 m beyond the canvas's edge while
    its rear half is inside (at 10 px/m, 2 m is more than the 10 px the view is grown by for lines)."""
    t, step, _, ego = busiest_step(merge_view)
    scale = 10.0
    width, height = page.evaluate("[document.getElementById('scene').clientWidth, "
                                  "document.getElementById('scene').clientHeight]")
    u = np.array([np.cos(t.heading[ego]), np.sin(t.heading[ego])])
    front = np.array([t.x[ego], t.y[ego]])
    # From the view's centre along the heading, the canvas's edge is `to_edge` metres away.
    to_edge = min(half / scale / abs(c) for half, c in ((width / 2, u[0]), (height / 2, u[1])) if abs(c) > 1e-9)
    centre = front - u * (to_edge + 2.0)
    page.evaluate("([x, y, s, k]) => { sumoRssViewer.setView(x, y, s); sumoRssViewer.seek(k); }",
                  [float(centre[0]), float(centre[1]), scale, step])
    assert scene_pixel(page, *front) == ()  # the front bumper is off the canvas
    rear_half = front - u * 0.75 * t.length[t.vehicle[ego]]
    assert scene_pixel(page, *rear_half) == EGO
    assert page.errors == []


def test_clicking_an_episode_in_the_sorted_list_jumps_to_its_t_b(page, merge_view):
    episodes = pd.read_csv(merge_view / "episodes.csv", keep_default_na=False)
    header = page.locator("#episodes th[data-key='duration_s']")
    header.click()
    header.click()  # descending
    durations = [float(v) for v in page.locator("#episodes tbody tr td:nth-child(4)").all_inner_texts()]
    assert durations == sorted(durations, reverse=True) and len(durations) == min(len(episodes), 1000)
    page.locator("#episodes tbody tr").first.click()
    longest = episodes.sort_values("duration_s", ascending=False, kind="stable").iloc[0]
    page.wait_for_function(f"document.getElementById('clock').textContent === '{longest.t_b_s:.1f} s'")
    state = page.evaluate("sumoRssViewer.state()")
    assert page.evaluate(f"sumoRssViewer.header.episodes.episode_key[{state['episode']}]") == longest.episode_key
    times = Trajectories.read(merge_view / "trajectories.npz").time
    expected_step = int(np.flatnonzero(np.isclose(times, longest.t_b_s))[0])
    assert int(page.locator("#slider").input_value()) == expected_step == state["step"]
    assert page.locator("#clock").inner_text() == f"{longest.t_b_s:.1f} s"
    assert page.locator("#episodes tr.selected").count() == 1
    assert page.errors == []


def test_the_selected_pairs_gap_chart_is_pair_states_csv(page, merge_view):
    states = pd.read_csv(merge_view / "pair_states.csv")
    key = states.episode_key.value_counts().index[0]  # the ego's longest traced episode
    rows = states[states.episode_key == key].reset_index(drop=True)
    page.locator("#filter").fill(key.split("|")[1])
    target = page.locator("#episodes tbody tr", has_text=key.split("|")[1]).filter(
        has=page.locator("td", has_text=f"{rows.time_s[0]:.1f}"))
    target.first.click()
    chart = page.evaluate("sumoRssViewer.chartData()")
    assert len(chart["time"]) == len(rows) > 20
    assert np.allclose(chart["time"], rows.time_s, atol=1e-6)
    for name in ("lon_gap", "lon_d_min", "lat_gap", "lat_d_min"):
        assert np.allclose(chart[name], rows[f"{name}_m"], atol=0.006, equal_nan=True), name  # 1 cm steps
    # Three steps on (arrow key): the readout shows that step's row.
    page.evaluate("document.activeElement.blur()")  # out of the filter box: the keys go to the page
    for _ in range(3):
        page.keyboard.press("ArrowRight")
    page.wait_for_function(f"document.querySelector(\"#readout td[data-field='time']\")?.textContent === "
                           f"'{rows.time_s[3]:.2f}'")  # drawn at the next frame
    for name in ("lon_gap", "lon_d_min"):
        shown = float(page.locator(f"#readout td[data-field='{name}']").inner_text())
        assert shown == pytest.approx(rows[f"{name}_m"][3], abs=0.011)  # 1 cm steps, shown to 2 decimals
    assert float(page.locator("#readout td[data-field='time']").inner_text()) == pytest.approx(rows.time_s[3])
    assert page.errors == []


def test_play_advances_the_time_and_pause_holds_it(page):
    import time

    page.evaluate("sumoRssViewer.seek(0)")
    start = page.evaluate("sumoRssViewer.state().time")
    frames = page.evaluate("sumoRssViewer.stats.frames")
    page.locator("#speed").select_option("4")
    started = time.perf_counter()
    page.locator("#play").click()
    page.wait_for_timeout(1000)
    page.locator("#play").click()
    wall = time.perf_counter() - started
    state = page.evaluate("sumoRssViewer.state()")
    # 4x: at most 4 simulated s per wall s (less where a loaded machine draws late)
    assert not state["playing"] and start < state["time"] <= start + 4 * wall + 0.1
    assert page.evaluate("sumoRssViewer.stats.frames") > frames + 2
    page.wait_for_timeout(300)
    assert page.evaluate("sumoRssViewer.state()")["time"] == state["time"]
