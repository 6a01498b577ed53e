"""The OLAT reflectance field (kornia_ilum_lab.synth.lightstage.field.ReflectanceField): layouts and sizes."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.scene import Camera


def field(size: int = 6, s: int = 4) -> ReflectanceField:
    """A dense field: a covered square in the middle, responses to the valid lights only."""
    alpha = torch.zeros(1, size, size)
    alpha[:, 2:4, 2:4] = 1.0
    values = torch.rand(3, size * size, s * s, generator=torch.Generator().manual_seed(0))
    values = values * alpha.flatten()[None, :, None] * mirror_ball_valid(s).flatten()
    return ReflectanceField(values.to(torch.bfloat16), alpha, torch.tensor([2.0, 2.0, 4.0, 4.0]),
                            Camera(30.0, 1.0, 0.0, 0.0, size=size), 3)


def test_sizes() -> None:
    rf = field()
    assert rf.size == 6 and rf.lighting_size == 4 and not rf.is_compact
    rf.meta["lighting_size"] = 4
    assert rf.lighting_size == 4


def test_compact_roundtrip() -> None:
    rf = field()
    rf.meta["lighting_size"] = 4
    compact = rf.to_compact()
    assert compact.is_compact and compact.field.shape == (3, 4, 12) and compact.to_compact() is compact
    assert torch.equal(compact.to_dense().field, rf.field) and rf.to_dense() is rf
    assert compact.subject_seed == 3 and compact.camera == rf.camera and compact.meta == rf.meta


def test_exception() -> None:
    compact = field().to_compact()
    compact.meta.clear()
    with pytest.raises(ValueCheckError, match="compact ReflectanceField needs meta"):
        compact.lighting_size  # noqa: B018
