"""kornia_ilum.bench.machine: the machine's limits, measured in the run."""

from __future__ import annotations

from kornia_ilum.bench import cpu_model, machine_limits, median_seconds, paired_median_seconds


def test_machine_limits_measure_every_peak_it_can() -> None:
    limits = machine_limits(quick=True)
    assert limits["cpu"] == cpu_model() and limits["threads"] >= 1
    assert limits["fp32_gflops"] > 0 and limits["int8_gops"] > 0
    assert limits["copy_gbps"] > 0 and limits["fresh_copy_gbps"] > 0
    assert limits["bf16_gflops"] is None or limits["bf16_gflops"] > 0  # None where bf16 would be emulated
    assert set(limits["flags"]) <= {"avx2", "avx512f", "avx512_vnni", "avx512_bf16", "amx_bf16", "amx_int8",
                                    "avx_vnni"}


def test_median_seconds_warms_up_then_times() -> None:
    calls = []
    assert median_seconds(lambda: calls.append(1), repeats=3, warmup=2) >= 0 and len(calls) == 5


def test_paired_median_seconds_times_each_in_turns() -> None:
    order: list[str] = []
    times = paired_median_seconds([lambda: order.append("a"), lambda: order.append("b")], repeats=4, rounds=2,
                                  warmup=1)
    assert len(times) == 2 and min(times) >= 0
    assert order == ["a"] * 3 + ["b"] * 3 + ["a"] * 3 + ["b"] * 3  # each round: 1 warm-up, then its 2 timed calls
