"""kornia_ilum_lab.bench.skips: the bench's skips section on a cache, or why it measured nothing."""

from __future__ import annotations

from kornia_ilum_lab.bench.skips import skip_rows
from tests.lab.bench.maps_helper import three_maps


def test_nothing_to_measure_says_why(tmp_path) -> None:
    rows, what = skip_rows([tmp_path], [three_maps(tmp_path / "hdri")], quick=True)
    assert rows == [] and "not measured" in what

