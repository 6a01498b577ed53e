"""The shipping rule: each clause against the shipped model's numbers and intervals."""

from __future__ import annotations

import copy

import pytest

from kornia_ilum_lab.evaluation.rule import rule_markdown, shipping_rule


def _method(diffuse: float, spread: float, flash: float, frontal: float, lr: float, grey: float) -> dict:
    return {
        "l_rec": {"all": {"diffuse": diffuse, "matte_silver": 0.10, "mirror": 0.20}},
        "checks": {
            "tone_spread": {"with/true": {"ratio": spread}},
            "flash": {"direction": {"all": {"median": flash, "ci": [flash - 3, flash + 3]},
                                    "within 25": {"median": frontal, "ci": [frontal - 4, frontal + 4]}},
                      "left_right": {"rate": lr, "ci": [lr - 0.02, min(lr + 0.02, 1.0)]}},
            "colour": {"eval": {"greyscale": {"angle": {"median": grey}, "angle_ci": [grey - 1, grey + 1]},
                                "warm": {"angle": {"median": 3.0}, "angle_ci": [2.5, 3.5]}}},
        },
    }


def _summary(**methods: dict) -> dict:
    return {"table1_l_rec": {n: m["l_rec"] for n, m in methods.items()},
            "checks": {n: m["checks"] for n, m in methods.items()}}


@pytest.fixture
def shipped() -> dict:
    return _method(0.090, 1.39, 30.0, 35.0, 0.98, 12.0)


def test_a_better_model_ships(shipped: dict) -> None:
    summary = _summary(ours=shipped, **{"ours@new": _method(0.091, 1.35, 22.0, 14.0, 0.99, 3.0)})
    verdict = shipping_rule(summary, "ours@new", "ours")
    assert verdict["ships"] and all(c["measured"] for c in verdict["clauses"])
    lines = rule_markdown([verdict])
    assert lines[-1].endswith("**yes** |")


@pytest.mark.parametrize(("change", "clause"), [
    ({"diffuse": 0.0935}, "L_rec diffuse within +3 %"),  # 3.9 % worse
    ({"spread": 1.45}, "tone spread of E with / true not larger"),
    ({"flash": 34.0}, "real flash: direction error, all (deg)"),  # above the shipped interval's top, 33
    ({"lr": 0.95}, "real flash: left/right agreement"),
    ({"grey": 13.5}, "colour check: greyscale, angle (deg)"),
])
def test_each_clause_can_stop_a_model(shipped: dict, change: dict, clause: str) -> None:
    values = {"diffuse": 0.090, "spread": 1.39, "flash": 30.0, "frontal": 35.0, "lr": 0.98, "grey": 12.0, **change}
    summary = _summary(ours=shipped, **{"ours@new": _method(**values)})
    verdict = shipping_rule(summary, "ours@new", "ours")
    failed = [c["clause"] for c in verdict["clauses"] if not c["pass"]]
    assert failed == [clause] and not verdict["ships"]


def test_noise_within_the_interval_is_not_worse(shipped: dict) -> None:
    summary = _summary(ours=shipped, **{"ours@new": _method(0.090, 1.39, 32.0, 38.0, 0.97, 12.9)})
    assert shipping_rule(summary, "ours@new", "ours")["ships"]


def test_what_was_not_measured_does_not_ship(shipped: dict) -> None:
    candidate = copy.deepcopy(shipped)
    del candidate["checks"]["flash"]
    verdict = shipping_rule(_summary(ours=shipped, **{"ours@new": candidate}), "ours@new", "ours")
    missing = [c for c in verdict["clauses"] if not c["measured"]]
    assert len(missing) == 3 and not verdict["ships"]
    with pytest.raises(KeyError):
        shipping_rule(_summary(ours=shipped), "ours@none", "ours")
