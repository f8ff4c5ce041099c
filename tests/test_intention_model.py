"""The intention network: masking, determinism, training on real SUMO data, weights and the rule fallback."""
from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import warnings

import numpy as np
import pytest
import torch

from conftest import SCENARIOS
from sumo_rss.errors import ScenarioError
from sumo_rss.planner.intention import dataset, estimator
from sumo_rss.planner.intention.estimator import SHIPPED_WEIGHTS, load_estimator, save_weights
from sumo_rss.planner.intention.features import HISTORY_FEATURES, HISTORY_STEPS, KEEP, LANE_POINTS, \
    MAX_CANDIDATES, lanes_branch
from sumo_rss.planner.intention.model import ARCHITECTURE, IntentionNet, nll_loss
from sumo_rss.planner.intention.train import TrainSettings, evaluate, predict, rule_probabilities, train
from sumo_rss.road.network import RoadNetwork
from sumo_rss.scenario import load_scenario, networks_root


def _random_inputs(n: int, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    history = torch.randn(n, HISTORY_STEPS, HISTORY_FEATURES, generator=g) * 5.0
    lanes = torch.randn(n, MAX_CANDIDATES, LANE_POINTS, 3, generator=g) * 20.0
    return history, lanes


@pytest.mark.parametrize("candidates", [1, 2, 3, 4, 5, 6])
def test_probabilities_sum_to_one_over_the_real_candidates_only(candidates):
    torch.manual_seed(0)
    net = IntentionNet(**ARCHITECTURE).eval()
    history, lanes = _random_inputs(4)
    mask = torch.zeros(4, MAX_CANDIDATES, dtype=torch.bool)
    mask[:, :candidates] = True
    with torch.inference_mode():
        p = torch.exp(net(history, lanes, mask))
        other_padding = lanes.clone()
        other_padding[:, candidates:] = 1e3  # whatever the padded lanes hold, they change nothing
        p2 = torch.exp(net(history, other_padding, mask))
    assert p.shape == (4, MAX_CANDIDATES)
    assert torch.allclose(p.sum(dim=1), torch.ones(4, dtype=p.dtype), atol=1e-6)
    assert torch.all(p[:, candidates:] == 0.0)
    assert torch.equal(p, p2)
    if candidates == 1:
        assert torch.all(p[:, 0] == 1.0)


def test_candidates_are_scored_independently_of_their_order():
    torch.manual_seed(0)
    net = IntentionNet(**ARCHITECTURE).eval()
    history, lanes = _random_inputs(3)
    mask = torch.zeros(3, MAX_CANDIDATES, dtype=torch.bool)
    mask[:, :3] = True
    swap = torch.tensor([2, 0, 1, 3, 4, 5])
    with torch.inference_mode():
        p, q = torch.exp(net(history, lanes, mask)), torch.exp(net(history, lanes[:, swap], mask[:, swap]))
    assert torch.allclose(p[:, swap], q, atol=1e-6)


@pytest.fixture(scope="module")
def merge_samples() -> dict[str, np.ndarray]:
    """Samples of 150 s of real merge_onramp traffic (no ego), seed 5."""
    spec = dataclasses.replace(load_scenario(SCENARIOS / "merge_onramp.toml"), ego=None)
    return dataset.record_run(spec.with_overrides(seed=5, duration_s=150.0))


def test_recording_gives_labelled_samples_where_lanes_branch_and_is_deterministic(merge_samples):
    data = merge_samples
    target, mask = data["target"], data["mask"]
    assert len(target) > 50
    assert set(data["family"].tolist()) == {"merge"}
    assert np.all(target <= mask) and np.all(target.any(axis=1))  # targets are real candidates, at least one
    assert np.all(target.sum(axis=1) < mask.sum(axis=1))  # something is decided
    assert np.all(mask.sum(axis=1) >= 2)
    assert np.all(lanes_branch(data["lateral"], mask, data["to_lane_end"]))
    assert np.all(data["history"][:, -1, :2] == 0.0)  # the agent frame's origin is the agent now
    assert target[:, 0].any() and target[:, 1].any()  # some stay on the acceleration lane a while, some merge
    spec = dataclasses.replace(load_scenario(SCENARIOS / "merge_onramp.toml"), ego=None)
    again = dataset.record_run(spec.with_overrides(seed=5, duration_s=150.0))
    assert all(np.array_equal(data[k], again[k]) for k in dataset.ARRAYS)


def test_a_car_keeping_its_lane_on_an_approach_targets_both_turns_of_its_lane():
    """N_in_0 of intersection_tls leads straight on and right. A car that stays on it, 80-90 m before the junction,
    is 3 s later on both those paths still, and on neither lane change: a sample whose target is the two keep
    candidates (not dropped as undecided, which left only lane-changers in the data there)."""
    net = RoadNetwork.from_file(networks_root() / "intersection_tls" / "intersection_tls.net.xml")
    steps = []
    for k in range(61):  # 6 s at 0.1 s, 10 m/s southwards from 110 m before the stop line
        t = 0.1 * k
        steps.append((t, np.array(["car"]), np.array([-4.8]), np.array([120.4 - 10.0 * t]), np.array([-np.pi / 2]),
                      np.array(["N_in_0"]), np.zeros(1), np.zeros(1), np.zeros(1, dtype=int)))
    data = dataset.samples_from_steps(net, steps, 0.1, "intersection_tls", 0, "intersection")
    assert data["time"].tolist() == [2.0, 2.5, 3.0]
    kept = data["lateral"][data["target"]].reshape(3, -1)
    assert kept.shape == (3, 2) and np.all(kept == KEEP)
    assert np.all(data["mask"].sum(axis=1) == 3)  # straight, right (its lane), left (the left-turn lane)


def test_a_short_training_run_lowers_the_loss_and_is_deterministic(merge_samples):
    data = merge_samples
    settings = TrainSettings(epochs=10, batch_size=32, learning_rate=5e-3, seed=3)

    def loss_of(net: IntentionNet) -> float:
        with torch.inference_mode():
            return float(nll_loss(net(torch.as_tensor(data["history"]), torch.as_tensor(data["lanes"]),
                                      torch.as_tensor(data["mask"])), torch.as_tensor(data["target"])))

    torch.manual_seed(settings.seed)
    untrained = loss_of(IntentionNet(**ARCHITECTURE))
    net = train(data, settings)
    assert loss_of(net) < 0.7 * untrained
    again = train(data, settings)
    assert all(torch.equal(a, b) for a, b in zip(net.state_dict().values(), again.state_dict().values()))
    assert np.array_equal(predict(net, data), predict(again, data))  # deterministic inference


def test_the_rule_baseline_spreads_each_lateral_class_over_its_candidates():
    data = {"mask": np.array([[True, True, True, False, False, False]]),
            "lateral": np.array([[0, 0, 1, 0, 0, 0]], dtype=np.int8),
            "offset": np.array([0.0]), "lat_speed": np.array([0.0]), "to_lane_end": np.array([np.inf])}
    p = rule_probabilities(data)[0]
    assert p[0] == pytest.approx(p[1]) and p[0] + p[1] + p[2] == pytest.approx(1.0)
    assert p[2] < 0.01 and np.all(p[3:] == 0.0)  # centred and not moving sideways: it keeps its lane


def test_weights_round_trip_and_bad_files_fall_back_to_the_rules_with_a_warning(tmp_path):
    torch.manual_seed(1)
    net = IntentionNet(**ARCHITECTURE)
    save_weights(net, ARCHITECTURE, tmp_path / "w.pt")
    loaded = load_estimator(tmp_path / "w.pt")
    assert loaded is not None
    assert all(torch.equal(a, b) for a, b in zip(net.state_dict().values(), loaded.net.state_dict().values()))
    torch.save({"format": 1, "architecture": {**ARCHITECTURE, "hidden": 32},
                "state_dict": net.state_dict()}, tmp_path / "shapes.pt")
    (tmp_path / "junk.pt").write_bytes(b"not a torch file")
    broken = {k: torch.full_like(v, float("nan")) if v.is_floating_point() else v for k, v in net.state_dict().items()}
    torch.save({"format": 1, "architecture": ARCHITECTURE, "state_dict": broken}, tmp_path / "nan.pt")
    for bad in ("missing.pt", "shapes.pt", "junk.pt", "nan.pt"):
        with pytest.warns(UserWarning, match="rule-based intention belief"):
            assert load_estimator(tmp_path / bad) is None


def test_the_planner_keeps_the_rules_when_the_weights_are_missing(monkeypatch, tmp_path):
    from sumo_rss.planner.epsilon import EpsilonPlanner
    from sumo_rss.road.network import RoadNetwork
    from sumo_rss.rss.auditor import ParamResolver

    net = RoadNetwork.from_file(load_scenario(SCENARIOS / "merge_onramp.toml").net_file)
    monkeypatch.setattr(estimator, "SHIPPED_WEIGHTS", tmp_path / "gone.pt")
    with pytest.warns(UserWarning, match="gone.pt"):
        planner = EpsilonPlanner(net, ParamResolver("ad_rss"))
    assert planner.belief is None
    monkeypatch.undo()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert EpsilonPlanner(net, ParamResolver("ad_rss")).belief is not None  # the shipped weights load


def test_the_shipped_weights_are_small_load_safely_and_beat_the_rules_on_held_out_seeds():
    assert SHIPPED_WEIGHTS.stat().st_size < 2_000_000
    payload = torch.load(SHIPPED_WEIGHTS, weights_only=True)
    assert payload["architecture"] == ARCHITECTURE
    card = json.loads(SHIPPED_WEIGHTS.with_suffix(".json").read_text())
    assert not set(card["data"]["train_seeds"]) & set(card["data"]["test_seeds"])
    for family in ("intersection", "merge"):
        held_out = card["held_out"][family]
        assert held_out["net"]["accuracy"] > held_out["rule"]["accuracy"]


@pytest.mark.parametrize("scenario", ["intersection_priority", "merge_onramp"])
def test_the_shipped_model_beats_the_rules_on_a_seed_it_never_saw(scenario):
    card = json.loads(SHIPPED_WEIGHTS.with_suffix(".json").read_text())
    seed = 777
    assert seed not in card["data"]["train_seeds"] + card["data"]["test_seeds"]
    spec = dataclasses.replace(load_scenario(SCENARIOS / f"{scenario}.toml"), ego=None)
    data = dataset.record_run(spec.with_overrides(seed=seed, duration_s=200.0))
    metrics = evaluate(load_estimator().net, data)["all"]
    assert metrics["samples"] > 100
    assert metrics["net"]["accuracy"] > metrics["rule"]["accuracy"]
    assert metrics["net"]["nll"] < metrics["rule"]["nll"]


def test_a_scenario_can_switch_the_network_off(tmp_path, valid_scenario):
    from conftest import write_scenario

    from sumo_rss.planner.driver import planner_config
    from sumo_rss.planner.epsilon import EpsilonPlanner
    from sumo_rss.road.network import RoadNetwork
    from sumo_rss.rss.auditor import ParamResolver

    valid_scenario["ego"]["controller"] = "epsilon"
    valid_scenario["ego"]["planner"] = {"intention_net": False}
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    assert spec.ego.planner.intention_net is False
    config = planner_config(spec)
    assert EpsilonPlanner(RoadNetwork.from_file(spec.net_file), ParamResolver("ad_rss"), config).belief is None
    valid_scenario["ego"]["planner"] = {"intention_net": "yes"}
    with pytest.raises(Exception, match="intention_net"):
        load_scenario(write_scenario(tmp_path, valid_scenario))


def test_recorded_data_is_reused_only_from_the_same_scenario_files_and_no_samples_is_an_error(tmp_path, monkeypatch):
    from conftest import SCENARIOS
    from sumo_rss.errors import SumoRssError
    from sumo_rss.planner.intention.pipeline import DataPlan, train_intent
    from sumo_rss.planner.intention.train import TrainSettings

    scenario = tmp_path / "merge_onramp.toml"
    scenario.write_text((SCENARIOS / "merge_onramp.toml").read_text())
    recorded = []
    generate = dataset.generate
    monkeypatch.setattr(dataset, "generate", lambda *a, **k: recorded.append(a[1]) or generate(*a, **k))
    plan, out = DataPlan((scenario,), (0,), (100,), 60.0), tmp_path / "out"
    for _ in range(2):  # the second run reuses both datasets
        train_intent(plan, out, TrainSettings(epochs=1), reuse_data=True, show_progress=False)
    assert recorded == [(0,), (100,)]
    scenario.write_text(scenario.read_text().replace("probability = 0.166667", "probability = 0.25"))  # same name
    train_intent(plan, out, TrainSettings(epochs=1), reuse_data=True, show_progress=False)
    assert recorded == [(0,), (100,)] * 2
    highway = DataPlan((SCENARIOS / "highway_dense.toml",), (0,), (100,), 20.0)
    with pytest.raises(SumoRssError, match="no samples in .*highway_dense.toml at seeds 0: .*--all-samples"):
        train_intent(highway, tmp_path / "hw", TrainSettings(epochs=1), show_progress=False)


@pytest.mark.parametrize("step_s, usable", [(0.1, True), (0.05, True), (0.25, False), (0.5, False), (0.3, False)])
def test_samples_need_a_step_that_divides_the_history_sampling_and_horizon(tmp_path, step_s, usable):
    """0.25 s spread the 11 history points 0.25 s apart (2.5 s of history, without a word); 0.5 s divided by zero in
    every recording process of train-intent."""
    if usable:
        dataset.check_step(step_s, "s.toml")
        return
    with pytest.raises(ScenarioError, match=r"s\.toml: step_s: intention samples need a step \[s\] that divides 0\.2 s "
                                            r"\(the history's spacing\), 0\.5 s \(sampling\) and 3 s \(horizon\), e\.g\. "
                                            rf"0\.1 or 0\.05, got {step_s!r}"):
        dataset.check_step(step_s, "s.toml")
    scenario = tmp_path / "coarse.toml"
    scenario.write_text((SCENARIOS / "merge_onramp.toml").read_text().replace("seed = 0", f"seed = 0\nstep_s = {step_s}"))
    proc = subprocess.run([sys.executable, "-m", "sumo_rss", "train-intent", "--scenarios", str(scenario),
                           "--train-seeds", "0", "--test-seeds", "100", "--out", str(tmp_path / "out"), "--quiet"],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 2 and "coarse.toml: step_s: intention samples" in proc.stderr
    assert f"got {step_s!r}" in proc.stderr and "Traceback" not in proc.stderr


def test_the_shipped_card_describes_the_shipped_weights():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_estimator() is not None


def test_a_card_with_another_size_or_architecture_warns_and_the_weights_are_still_used(tmp_path):
    """Nothing read intention.json: a card with another size or architecture than the weights beside it (a .pt
    copied without its card) was taken as theirs without a word."""
    torch.manual_seed(0)
    weights = tmp_path / "intention.pt"
    save_weights(IntentionNet(**ARCHITECTURE), ARCHITECTURE, weights)
    card = {"weights_bytes": weights.stat().st_size, "architecture": {**ARCHITECTURE, "lane_channels": [32, 64]}}
    (tmp_path / "intention.json").write_text(json.dumps(card))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_estimator(weights) is not None  # the card agrees
    (tmp_path / "intention.json").write_text(json.dumps({**card, "weights_bytes": 1,
                                                         "architecture": {**card["architecture"], "hidden": 32}}))
    with pytest.warns(UserWarning, match=r"intention\.json does not describe intention\.pt \(weights_bytes: card 1, "
                                         r"weights \d+; architecture: card .*'hidden': 32.*\): its data and figures"):
        assert load_estimator(weights) is not None
