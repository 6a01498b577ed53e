"""kornia_ilum.bench.stress: no public op returns garbage or an untyped error across eight orders of magnitude
of lighting in float32, bfloat16 and float16, nor on meta tensors; and the table says so."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.bench.stress import (
    DTYPES,
    OPS,
    StressRow,
    format_stress,
    lighting_cases,
    stress_meta,
    stress_ops,
)


@pytest.mark.parametrize("op", sorted(OPS))
def test_no_op_returns_garbage_or_an_untyped_error(op) -> None:
    rows = stress_ops({op: OPS[op]})
    assert len(rows) == len(DTYPES) * len(lighting_cases(OPS[op][0], torch.float32))
    failed = [r for r in rows if r.failed]
    assert not failed, format_stress(failed)


def test_finite_float32_inputs_in_range_are_answered() -> None:
    """Where float32 holds the input and the op takes it, the answer is a number, not a refusal."""
    rows = stress_ops({k: OPS[k] for k in ("render_spheres", "rotate_lighting", "sh_project",
                                            "latlong_to_mirror_ball", "total_radiance")}, dtypes=(torch.float32,))
    refused = [r for r in rows if r.case != "NaN pixel" and r.outcome != "ok"]
    assert not refused, format_stress(refused)
    assert all(r.outcome == "typed error" and "NonFiniteError" in r.detail for r in rows if r.case == "NaN pixel")


def test_float16_cannot_hold_a_sun_and_says_so() -> None:
    rows = stress_ops({"render_spheres": OPS["render_spheres"]}, dtypes=(torch.float16,))
    sun = next(r for r in rows if r.case == "uniform 1e+06")
    assert sun.outcome == "typed error" and "NonFiniteError" in sun.detail  # the cast made it Inf


def test_meta_tensors_give_shapes_or_typed_errors() -> None:
    rows = stress_meta()
    assert len(rows) == len(OPS)
    failed = [r for r in rows if r.failed]
    assert not failed, format_stress(failed)
    shapes = {r.op: r.detail for r in rows if r.outcome == "ok"}
    assert "(1, 3, 32, 32)" in shapes["latlong_to_mirror_ball"]


def test_the_table_lists_failures_first() -> None:
    rows = [StressRow("a", "float32", "x", "ok", "fine"), StressRow("b", "float16", "y", "garbage", "NaN")]
    text = format_stress(rows)
    assert text.index("| b |") < text.index("| a |") and "garbage: 1, ok: 1" in text


def test_lighting_cases_on_another_device() -> None:
    """The cases are built on the CPU and moved: a device other than the CPU gets them all (``meta`` here)."""
    for kind in ("mirror_ball", "latlong"):
        cases = lighting_cases(kind, torch.float32, "meta")
        assert all(v.device.type == "meta" and v.dtype == torch.float32 for v in cases.values())
