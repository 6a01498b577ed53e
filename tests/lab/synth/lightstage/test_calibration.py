"""The uniform-white check (kornia_ilum_lab.synth.lightstage.calibration)."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.geometry import mirror_ball_solid_angles, mirror_ball_valid
from kornia_ilum_lab.synth.lightstage import ReflectanceField
from kornia_ilum_lab.synth.lightstage.calibration import check_skin, face_mask, uniform_response
from kornia_ilum_lab.synth.lightstage.scene import Camera
from kornia_ilum_lab.synth.lightstage.subjects import LANDMARK_NAMES
from kornia_ilum_lab.synth.lightstage.subjects.skin import SKIN_ALBEDO, SKIN_SPECULAR_ALBEDO

SIZE, S = 24, 8


def _landmarks() -> torch.Tensor:
    """A face filling the middle of a 24-pixel image."""
    lm = torch.full((len(LANDMARK_NAMES), 2), 12.0)
    where = {"brow_right_top": (6, 5), "brow_left_top": (18, 5), "eye_right_outer": (5, 8), "eye_left_outer": (19, 8),
             "cheek_right": (6, 13), "cheek_left": (18, 13), "jaw_right": (7, 18), "jaw_left": (17, 18),
             "chin": (12, 21)}  # fmt: skip
    for name, xy in where.items():
        lm[LANDMARK_NAMES.index(name)] = torch.tensor(xy, dtype=torch.float32)
    return lm


def _field(total: tuple[float, float, float], skin: float = 1.0) -> ReflectanceField:
    """A flat field whose uniform-white reading is ``total`` everywhere: each light's share is its solid angle."""
    omega = (mirror_ball_solid_angles(S) * mirror_ball_valid(S)).flatten()
    share = omega / omega.sum()
    field = torch.tensor(total)[:, None, None] * share[None, None, :].expand(3, SIZE * SIZE, S * S)
    albedo = torch.tensor(total)[:, None, None].expand(3, SIZE, SIZE) - SKIN_SPECULAR_ALBEDO
    return ReflectanceField(field.to(torch.bfloat16), torch.ones(1, SIZE, SIZE), torch.tensor([5.0, 5.0, 19.0, 21.0]),
                            Camera(30.0, 1.0, 0.0, 0.0, size=SIZE), 3,
                            {"landmarks": _landmarks().tolist(), "view_index": 0, "lighting_size": S},
                            albedo=albedo.clone(), skin=torch.full((1, SIZE, SIZE), skin))


def test_uniform_response_sums_the_lights():
    torch.testing.assert_close(uniform_response(_field((0.4, 0.3, 0.2)))[:, 3, 3], torch.tensor([0.4, 0.3, 0.2]),
                               atol=3e-3, rtol=0)


def test_face_mask_is_inside_the_outline():
    mask = face_mask(_landmarks(), SIZE)
    assert mask[12, 12] and not mask[0, 0] and not mask[23, 12] and 100 < int(mask.sum()) < 300


def test_check_passes_calibrated_skin():
    tone = 3
    total = tuple(a + SKIN_SPECULAR_ALBEDO for a in SKIN_ALBEDO[tone - 1])
    result = check_skin(_field(total), tone)
    assert result.ok and result.pixels > 100
    torch.testing.assert_close(torch.tensor(result.energy), torch.ones(3), atol=0.01, rtol=0)


def test_check_fails_skin_that_creates_energy_or_is_too_light():
    tone = 3
    total = tuple(a + SKIN_SPECULAR_ALBEDO for a in SKIN_ALBEDO[tone - 1])
    brighter = _field(total)
    brighter.field = brighter.field * 1.3  # subsurface that creates 30 % more light than the albedo
    assert not check_skin(brighter, tone).energy_ok
    too_light = check_skin(_field(total), 9)  # tone 3's skin is far lighter than measured tone-9 faces
    assert too_light.energy_ok and not too_light.skin_ok


def test_check_needs_the_cached_buffers():
    field = _field((0.4, 0.3, 0.2))
    field.albedo = None
    with pytest.raises(ValueCheckError, match="rebuild the cache"):
        check_skin(field, 3)
    with pytest.raises(ValueCheckError, match="no skin pixel"):
        check_skin(_field((0.4, 0.3, 0.2), skin=0.0), 3)


@pytest.mark.slow
def test_makehuman_face_reflects_its_albedo(mh, variant):
    """A MakeHuman subject rendered by the one-pass renderer (subsurface on) passes the uniform-white check."""
    from kornia_ilum_lab.synth.lightstage import render_olat  # lazy: the renderer imports Mitsuba
    from kornia_ilum_lab.synth.lightstage.scene import sample_views
    from kornia_ilum_lab.synth.lightstage.settings import OnePass

    if not variant.startswith("llvm"):
        pytest.fail("the one-pass renderer needs llvm_ad_rgb")
    subject = mh.sample(5)
    camera = sample_views(5, 1, size=96, landmarks=subject.face_landmarks)[0]
    field = render_olat(subject, camera, settings=OnePass(lighting_size=16), threads=1)
    result = check_skin(field, subject.skin_tone)
    assert result.ok, result


def test_check_judges_the_documented_albedo_not_the_occluded_reading():
    """A face that hides 12 % of the uniform light from itself reads less than its albedo: its energy ratio
    says so, and its skin colour is still judged by the albedo (the reading would fall below tone 3's range)."""
    tone = 3
    total = tuple(a + SKIN_SPECULAR_ALBEDO for a in SKIN_ALBEDO[tone - 1])
    occluded = _field(total)
    occluded.field = occluded.field * 0.88
    result = check_skin(occluded, tone)
    assert result.ok
    torch.testing.assert_close(torch.tensor(result.total), torch.tensor(total), atol=1e-3, rtol=0)
    torch.testing.assert_close(torch.tensor(result.energy), torch.full((3,), 0.88), atol=0.01, rtol=0)


def _write_cache(out, fields_tones):
    import json

    from kornia_ilum_lab.synth.lightstage.cache import field_path, write_field

    entries = []
    for seed, (field, tone) in enumerate(fields_tones):
        field.subject_seed = seed
        write_field(out / field_path(seed, 0), field)
        entries.append({"subject_seed": seed, "view_index": 0, "path": field_path(seed, 0), "split": "train",
                        "skin_tone": tone})
    (out / "manifest.json").write_text(json.dumps({"format": "kornia_ilum.olat-cache.v2", "entries": entries}))
    return out


def test_check_skin_command_prints_each_view_and_fails_on_a_bad_one(tmp_path, capsys):
    import json

    from kornia_ilum.cli import main

    tone = 3
    total = tuple(a + SKIN_SPECULAR_ALBEDO for a in SKIN_ALBEDO[tone - 1])
    brighter = _field(total)
    brighter.field = brighter.field * 1.3
    good = _write_cache(tmp_path / "good", [(_field(total), tone)])
    assert main(["synth", "check-skin", "--cache", str(good), "--split", "all"]) == 0
    assert "1 of 1 subject-views passed" in capsys.readouterr().out
    bad = _write_cache(tmp_path / "bad", [(_field(total), tone), (brighter, tone)])
    out = tmp_path / "skin.json"
    assert main(["synth", "check-skin", "--cache", str(bad), "--split", "all", "--json", str(out)]) == 1
    printed = capsys.readouterr().out
    assert "1 of 2 subject-views passed" in printed and printed.count(" ok\n") == 1 and "energy" in printed
    rows = json.loads(out.read_text())
    assert [r["subject_seed"] for r in rows] == [0, 1] and rows[1]["energy"][0] > 1.2
    assert main(["synth", "check-skin", "--cache", str(good)]) == 1  # no eval subject: a one-line error
    assert "no reflectance field" in capsys.readouterr().err


def test_every_part_of_makehuman_subjects_reflects_a_plausible_share(mh):
    """Hair, brows, lashes, beards, eyes, teeth, glasses and hats of 24 subjects inside their ranges."""
    from kornia_ilum_lab.synth.lightstage.calibration import check_parts

    seen = set()
    for seed in range(24):
        for check in check_parts(mh.sample(seed)):
            assert check.ok, (seed, check)
            seen.add("beard" if check.name.startswith("beard") else check.name)
    assert {"hair", "brows", "lashes", "eyes", "teeth", "glasses", "beard"} <= seen


def test_part_check_catches_a_part_that_reflects_too_much():
    import dataclasses

    from kornia_ilum_lab.synth.lightstage.calibration import check_parts
    from kornia_ilum_lab.synth.lightstage.subjects import MannequinSource

    subject = MannequinSource().sample(0)
    assert all(c.ok for c in check_parts(subject))
    i = next(i for i, p in enumerate(subject.parts) if p.name == "sclera")
    part = subject.parts[i]
    subject.parts[i] = dataclasses.replace(part, material=dataclasses.replace(part.material, albedo=(0.95,) * 3,
                                                                            albedo_texture=None))
    assert not next(c for c in check_parts(subject) if c.name == "sclera").ok
