"""Angle conventions at the SUMO boundary, and which modules may import libsumo."""
from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from conftest import REPO
from sumo_rss.sim.snapshot import compass_deg_to_heading, heading_to_compass_deg


@pytest.mark.parametrize("compass, heading", [(90.0, 0.0), (0.0, math.pi / 2), (180.0, -math.pi / 2),
                                              (270.0, math.pi), (45.0, math.pi / 4), (359.0, math.radians(91))])
def test_sumo_compass_angle_to_math_heading(compass, heading):
    assert compass_deg_to_heading(compass) == pytest.approx(heading)
    assert heading_to_compass_deg(heading) == pytest.approx(compass % 360.0)


def test_heading_is_wrapped_to_minus_pi_pi():
    headings = compass_deg_to_heading(np.linspace(0.0, 720.0, 1441))
    assert np.all(headings > -math.pi) and np.all(headings <= math.pi)


def test_only_the_sim_package_imports_libsumo():
    code = ("import sys, sumo_rss, sumo_rss.scenario, sumo_rss.rss.params, sumo_rss.road.topology, "
            "sumo_rss.sim.snapshot, sumo_rss.trajectory, sumo_rss.cli; print('libsumo' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True)
    assert proc.stdout.strip() == "False"
