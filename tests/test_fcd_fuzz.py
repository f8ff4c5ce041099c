"""A property-based FCD fuzzer: a real FCD (a second of a SUMO run on the highway) with its attributes and structure
mutated (absurd numbers, text, deleted, doubled and swapped elements, cut files, inserted bytes, gzipped and damaged
gzip streams, lanes of elsewhere in the network) is audited as `sumo-rss audit` audits it. Each example ends either
with CSVs whose numbers are all finite and sane, or with one error of one line that names the file (exit 2 at the
command line); nothing else, no traceback (docs/outputs.md, "Bad input, full disks and interruptions").

The audit runs in this process (the reader, the auditor and the CSV writer of the command, without starting Python
and SUMO for each example), derandomized: the same 200 examples in every run of the suite."""
from __future__ import annotations

import gzip
import re
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import NETWORKS, VALID_SCENARIO, write_scenario
from sumo_rss import load_scenario
from sumo_rss.batch.runner import run_one
from sumo_rss.errors import SumoRssError
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.fcd import audit_fcd, read_vehicle_info

HIGHWAY = NETWORKS / "highway" / "highway.net.xml"
WINDOW = (3.0, 4.0)  # [s] the time steps of the run kept as the base FCD
SANE = 1e10  # no number in a CSV is larger than this (coordinates stay below 1e8 m, times below 1e9 s)
NUMBER_COLUMNS = {"episodes.csv": ("t_b_s", "t_end_s", "duration_s", "min_lon_margin_m", "min_lat_margin_m"),
                  "violations.csv": ("bound", "worst_actual", "excess", "t_start_s", "t_end_s"),
                  "collisions.csv": ("time_s",)}
ATTRIBUTES = ("id", "x", "y", "angle", "type", "speed", "acceleration", "pos", "lane", "posLat", "speedLat",
              "signals")
_VEHICLE = re.compile(r'^(\s*<vehicle )(.*?)(/>)$')
_ATTRIBUTE = re.compile(r'(\w+)="([^"]*)"')


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """The base FCD's lines, the network and the run's vehicles (vTypes as SUMO resolves them)."""
    folder = tmp_path_factory.mktemp("fuzz")
    data = {**VALID_SCENARIO, "duration_s": 5.0, "seed": 3}
    data["demand"] = {**data["demand"], "flows": [{"id": "main", "route": ["hw0", "hw1", "hw2"],
                                                   "veh_per_hour": 7000}]}
    spec = load_scenario(write_scenario(folder, data))
    run_one(spec, folder / "out", fcd=True)
    run = folder / "out" / spec.name / str(spec.seed)
    lines = (run / "fcd.xml").read_text().splitlines(keepends=True)
    steps = [k for k, line in enumerate(lines) if "<timestep " in line]
    times = [float(re.search(r'time="([^"]+)"', lines[k]).group(1)) for k in steps]
    first = steps[times.index(WINDOW[0])]
    last = steps[times.index(WINDOW[1])]
    header = lines[:steps[0]]
    kept = header + lines[first:last] + ["</fcd-export>\n"]
    assert sum("<vehicle " in line for line in kept) >= 30  # several cars in every step
    return kept, RoadNetwork.from_file(HIGHWAY), read_vehicle_info(run / "routes.rou.xml", HIGHWAY)


NASTY_TEXT = st.sampled_from(["", "nan", "NaN", "-inf", "inf", "1e300", "-1e300", "1e308", "9" * 5000, "-0",
                              "0x10", " 5", "1_000", "\u0663", "1e-320", "4.9e-324", "3.0.1", "<", "&amp;", "\u00e9",
                              "99999999999999999999999", "-1", "360", "1e12", "hw0_0", ":h1_0_0", "hw2_2",
                              "nowhere_0", "DEFAULT_VEHTYPE", "ego_type", "a" * 300])
NUMBERS = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                    st.integers(min_value=-10**30, max_value=10**30).map(str),
                    st.floats(min_value=-1e4, max_value=1e4).map(lambda v: f"{v:.6f}"))
VALUES = st.one_of(NASTY_TEXT, NUMBERS, st.text(max_size=12))


@st.composite
def mutations(draw, size: int):
    """A list of (kind, arguments) edits of a file of ``size`` lines."""
    line = st.integers(min_value=0, max_value=size - 1)
    one = st.one_of(
        st.tuples(st.just("attribute"), line, st.sampled_from(ATTRIBUTES), VALUES),
        st.tuples(st.just("delete-attribute"), line, st.sampled_from(ATTRIBUTES)),
        st.tuples(st.just("time"), line, VALUES),
        st.tuples(st.just("delete-line"), line),
        st.tuples(st.just("double-line"), line),
        st.tuples(st.just("swap-lines"), line, line),
        st.tuples(st.just("insert"), line, st.binary(min_size=1, max_size=12)),
        st.tuples(st.just("cut"), st.floats(min_value=0.0, max_value=1.0)),
    )
    return draw(st.lists(one, min_size=1, max_size=3)), draw(st.sampled_from(["plain", "gzip", "damaged gzip"]))


def mutated(lines: list[str], edits: list[tuple]) -> bytes:
    """The FCD ``lines`` with ``edits`` applied, as bytes."""
    lines = list(lines)
    cut = None
    for kind, *args in edits:
        k = args[0] % len(lines) if args and isinstance(args[0], int) else 0
        if kind == "attribute" or kind == "delete-attribute":
            match = _VEHICLE.match(lines[k].rstrip("\n"))
            if match:
                attributes = dict(_ATTRIBUTE.findall(match.group(2)))
                if kind == "attribute":
                    attributes[args[1]] = args[2].replace('"', "&quot;")
                else:
                    attributes.pop(args[1], None)
                body = " ".join(f'{name}="{value}"' for name, value in attributes.items())
                lines[k] = f"{match.group(1)}{body}{match.group(3)}\n"
        elif kind == "time" and "<timestep " in lines[k]:
            lines[k] = re.sub(r'time="[^"]*"', f'time="{args[1]}"'.replace("\\", ""), lines[k])
        elif kind == "delete-line":
            del lines[k]
        elif kind == "double-line":
            lines.insert(k, lines[k])
        elif kind == "swap-lines":
            j = args[1] % len(lines)
            lines[k], lines[j] = lines[j], lines[k]
        elif kind == "insert":
            lines.insert(k, args[1].decode("latin-1"))
        elif kind == "cut":
            cut = args[0]
    data = "".join(lines).encode("utf-8", errors="surrogateescape")
    return data if cut is None else data[:int(cut * len(data))]


def check_csvs(out: Path) -> None:
    """Every number in the audit's CSVs is finite and sane (empty cells are allowed where a run writes them)."""
    for name, columns in NUMBER_COLUMNS.items():
        frame = pd.read_csv(out / name, dtype=str, keep_default_na=False)
        for column in columns:
            cells = frame[column][frame[column] != ""]
            values = pd.to_numeric(cells, errors="coerce").to_numpy(dtype=float)
            assert np.isfinite(values).all() and (np.abs(values) <= SANE).all(), (name, column, cells.tolist()[:5])


@settings(max_examples=200, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                 HealthCheck.data_too_large])
@given(data=st.data())
def test_a_mutated_fcd_gives_finite_csvs_or_one_line_naming_the_file(base, data):
    lines, network, vehicles = base
    edits, packing = data.draw(mutations(len(lines)))
    content = mutated(lines, edits)
    with tempfile.TemporaryDirectory(prefix="sumo_rss_fuzz_") as folder:
        fcd = Path(folder) / ("fcd.xml.gz" if packing != "plain" else "fcd.xml")
        if packing == "plain":
            fcd.write_bytes(content)
        else:
            packed = bytearray(gzip.compress(content, mtime=0))
            if packing == "damaged gzip":
                middle = len(packed) // 2
                packed[middle:middle + 4] = bytes(b ^ 0x5A for b in packed[middle:middle + 4])
            fcd.write_bytes(bytes(packed))
        out = Path(folder) / "out"
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # warned about (cut files, unknown vTypes, ...): still audited
                result = audit_fcd(fcd, network, ParamResolver(), vehicles=vehicles)
                result.to_csv(out)
        except SumoRssError as exc:  # the command line prints it as one line and exits with code 2
            message = str(exc)
            assert "\n" not in message and str(fcd) in message and len(message) < 1000, message
            assert not out.exists()
            return
        check_csvs(out)
